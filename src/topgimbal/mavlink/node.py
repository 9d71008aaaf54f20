"""The bridge's place on the MAVLink network: its links, one parser per (link, peer), and the
components it speaks as (each a pymavlink encoder with its own sequence numbers).

Everything a component sends goes out on every link (a MAVLink node broadcasts; routers and
ground stations sort it out). Messages our own components sent, echoed back by a router, are
dropped on arrival.

With a signing key (`signing.py`) every component signs what it sends and the node refuses what is
not signed with the key or is a replay (`SignedStreams`: one replay state per (link id, system,
component) for the whole node, not per peer address); the first refusal from each peer is logged
(a warning naming the peer, the claimed system/component and why), later ones are counted in
`unsigned_in`. `_on_data` says whether anything in the bytes was accepted: a UDP address that sent
nothing signed becomes no peer (it takes no place and is sent no telemetry)."""

from __future__ import annotations

import logging
from collections.abc import Callable, Hashable, Iterable, Sequence
from typing import TYPE_CHECKING, Any

from ..camdef.pacing import FetchPacer
from ..clock import monotonic
from ..links import memory_link  # noqa: F401  # registers the memory:NAME kind with make_link
from ..links.base import link_peer as link_peer  # where it was before links/ (issue 44)
from ..links.base import tag_peer
from ..links.endpoints import MAX_PEERS, DataCallback, GoneCallback, Link, make_link
from ..links.mav import mavlink
from ..links.signing import SignedStreams, sign_outgoing

if TYPE_CHECKING:
    from ..links.mav import MAVLinkCodec, MAVLinkMessage

log = logging.getLogger("topgimbal.mavlink")

MessageCallback = Callable[[Any], None]
LinkFactory = Callable[[DataCallback, GoneCallback], Link]  # a link made elsewhere (zenoh_link.py)
MAX_REFUSAL_LOGGED = 1024  # peers whose first refusal was logged (then forgotten all at once)


class _Writer:
    """The file pymavlink's encoder writes to: every link of the node."""

    def __init__(self, node: Node) -> None:
        self.node = node

    def write(self, data: bytes) -> None:
        self.node.broadcast(data)


class _OneWriter:
    """The file pymavlink's encoder writes to for a reply to one peer."""

    def __init__(self, node: Node, origin: Hashable) -> None:
        self.node = node
        self.origin = origin

    def write(self, data: bytes) -> None:
        self.node.send_to(self.origin, data)


class Component:
    """One MAVLink identity (system id, component id) of the bridge."""

    def __init__(self, node: Node, compid: int, name: str) -> None:
        self.node = node
        self.sysid = node.sysid
        self.compid = compid
        self.name = name
        self.mav = mavlink().MAVLink(_Writer(node), srcSystem=node.sysid, srcComponent=compid)
        self.mav.robust_parsing = True
        if node.signing_key is not None:
            sign_outgoing(self.mav, node.signing_key)
        self.sent = 0

    def send(self, msg: MAVLinkMessage) -> None:
        self.mav.send(msg)
        self.sent += 1

    def send_to(self, msg: MAVLinkMessage, origin: Hashable) -> None:
        """Send to one peer only: `origin` is `link_peer()` of the message answered (a reply
        nobody else asked for, such as MAVLink FTP's). Same sequence numbers and signing."""
        writer = self.mav.file
        self.mav.file = _OneWriter(self.node, origin)
        try:
            self.mav.send(msg)
        finally:
            self.mav.file = writer
        self.sent += 1

    def __repr__(self) -> str:
        return f"<{self.name} {self.sysid}/{self.compid}>"


class Node:
    def __init__(
        self,
        sysid: int,
        endpoints: list[str],
        *,
        max_peers: int = MAX_PEERS,
        signing_key: bytes | None = None,
        link_factories: Sequence[LinkFactory] = (),
    ) -> None:
        self.sysid = sysid
        self.signing_key = signing_key
        self.unsigned_in = 0  # messages refused for a missing or wrong signature
        self._unsigned_logged: set[tuple[int, Hashable]] = set()
        self.signed = SignedStreams(signing_key) if signing_key is not None else None
        self.links: list[Link] = [make_link(e, self._on_data, self._on_gone, max_peers) for e in endpoints]
        self.links += [make(self._on_data, self._on_gone) for make in link_factories]
        for link in self.links:
            link.needs_trust = signing_key is not None
        self.components: dict[int, Component] = {}
        self._parsers: dict[tuple[int, Hashable], Any] = {}
        self._subscribers: list[MessageCallback] = []
        self._handlers: dict[str, list[MessageCallback]] = {}  # by message name: on()
        self._peer_watchers: list[Callable[[Link, Hashable], None]] = []
        self._gone_subscribers: list[Callable[[Hashable], None]] = []
        self.messages_in = 0
        self.bad_in = 0
        self.started = monotonic()
        # the cameras' definition downloads, one at a time for every bridge on this node (camdef/pacing.py)
        self.definition_pacer: FetchPacer | None = None

    def component(self, compid: int, name: str) -> Component:
        if compid in self.components:
            raise ValueError(f"component id {compid} is used twice")
        c = self.components[compid] = Component(self, compid, name)
        return c

    def subscribe(self, callback: MessageCallback) -> None:
        """`callback(msg)` for every message heard (a tap: logs, statistics). A part that handles
        some messages registers for them with `on()` instead."""
        self._subscribers.append(callback)

    def on(self, names: str | Iterable[str], handler: MessageCallback) -> None:
        """`handler(msg)` for each message of these names (pymavlink's, e.g. "COMMAND_LONG"): the
        node looks the handlers up by the message's name, so a message reaches only the parts that
        handle it (docs/architecture.md, "Handle a new MAVLink message")."""
        for name in [names] if isinstance(names, str) else names:
            if name not in _message_names():
                raise ValueError(f"{name!r} is not a MAVLink message of the common dialect")
            self._handlers.setdefault(name, []).append(handler)

    def on_new_peer(self, callback: Callable[[Link, Hashable], None]) -> None:
        """`callback(link, peer)` when a peer is first heard on a link (the bridge greets it with a
        HEARTBEAT at once rather than at its next 1 Hz beat)."""
        self._peer_watchers.append(callback)

    def on_peer_gone(self, callback: Callable[[Hashable], None]) -> None:
        """`callback((str(link), peer))` when a peer's connection closes or it is forgotten (the
        same key `link_peer()` gives its messages)."""
        self._gone_subscribers.append(callback)

    def time_boot_ms(self) -> int:
        return int((monotonic() - self.started) * 1000) & 0xFFFFFFFF

    async def start(self) -> None:
        started: list[Link] = []
        try:
            for link in self.links:
                await link.start()
                started.append(link)
        except BaseException:
            for link in started:
                await link.close()
            raise

    async def close(self) -> None:
        for link in self.links:
            await link.close()
        self._parsers.clear()

    def broadcast(self, data: bytes) -> None:
        for link in self.links:
            try:
                link.send(data)
            except OSError as exc:  # a link in trouble must not stop the others
                link.dropped_out += 1
                log.debug("%s: send failed: %s", link, exc)

    def send_to(self, origin: Hashable, data: bytes) -> None:
        """Bytes to the one peer `origin` ((str(link), peer), as `link_peer` gives) came from."""
        if not isinstance(origin, tuple) or len(origin) != 2:
            return
        for link in self.links:
            if str(link) == origin[0]:
                try:
                    link.send_to(origin[1], data)
                except OSError as exc:
                    link.dropped_out += 1
                    log.debug("%s: send failed: %s", link, exc)
                return

    def _parser(self, link: Link, peer: Hashable) -> MAVLinkCodec:
        key = (id(link), peer)
        p = self._parsers.get(key)
        if p is None:
            p = mavlink().MAVLink(None)
            p.robust_parsing = True  # no key: signatures are checked by the node's SignedStreams
            self._parsers[key] = p
            for cb in list(self._peer_watchers):
                try:
                    cb(link, peer)
                except Exception:
                    log.exception("%s: greeting new peer %s failed", link, peer)
        return p

    def _on_gone(self, link: Link, peer: Hashable) -> None:
        self._parsers.pop((id(link), peer), None)
        self._unsigned_logged.discard((id(link), peer))
        for cb in list(self._gone_subscribers):
            try:
                cb((str(link), peer))
            except Exception:
                log.exception("handling the end of %s on %s failed", peer, link)

    def _refused_signature(self, link: Link, peer: Hashable, data: bytes, kind: str) -> None:
        self.unsigned_in += 1
        key = (id(link), peer)
        if key in self._unsigned_logged:
            return
        if len(self._unsigned_logged) >= MAX_REFUSAL_LOGGED:
            self._unsigned_logged.clear()
        self._unsigned_logged.add(key)
        at = 5 if data[:1] == b"\xfd" else 3  # where system and component ids are: MAVLink 2, 1
        sysid, compid = (data[at], data[at + 1]) if len(data) > at + 1 else (0, 0)
        log.warning(
            "%s: refusing messages from %s (system %d, component %d): %s; --signing-key is set, only messages "
            "signed with that key and not replayed are accepted (logged once per peer; see docs/mavlink.md, signing)",
            link, peer, sysid, compid, kind,
        )  # fmt: skip

    def _on_data(self, link: Link, peer: Hashable, data: bytes) -> bool:
        """Hands the messages in `data` to the subscribers; False when a signing key is set and
        nothing in `data` was signed with it (the link then takes the sender for no peer)."""
        known = (id(link), peer) in self._parsers
        parser = self._parser(link, peer)
        try:
            msgs = parser.parse_buffer(data) or []
        except Exception as exc:  # robust_parsing turns most garbage into BAD_DATA; be sure
            self.bad_in += 1
            log.debug("%s: unparsable bytes from %s: %s", link, peer, exc)
            self._parsers.pop((id(link), peer), None)  # start afresh rather than trust its state
            return self.signed is None
        _compact(parser)
        accepted = self.signed is None
        for m in msgs:
            if m.get_type() == "BAD_DATA":
                self.bad_in += 1
                continue
            if self.signed is not None:
                frame = bytes(m.get_msgbuf())
                why = self.signed.check(frame)
                if why is not None:
                    self._refused_signature(link, peer, frame, why)
                    continue
                accepted = True
            if m.get_srcSystem() == self.sysid and m.get_srcComponent() in self.components:
                continue  # our own message, echoed by a router
            self.messages_in += 1
            tag_peer(m, link, peer)
            for cb in [*self._subscribers, *self._handlers.get(m.get_type(), ())]:
                try:
                    cb(m)
                except Exception:
                    log.exception(
                        "handling %s from %d/%d failed", m.get_type(), m.get_srcSystem(), m.get_srcComponent()
                    )
        if not accepted and not known:
            self._parsers.pop((id(link), peer), None)  # a sender that is no peer keeps no parser
        return accepted


_NAMES: frozenset[str] = frozenset()


def _message_names() -> frozenset[str]:
    global _NAMES
    if not _NAMES:
        _NAMES = frozenset(cls.msgname for cls in mavlink().mavlink_map.values())
    return _NAMES


def _compact(parser: MAVLinkCodec) -> None:
    """Drop the bytes pymavlink's parser has consumed. It frees its buffer only when a chunk ends
    exactly at a packet boundary; on a byte stream (TCP, serial) whose chunks always split a packet
    the consumed bytes were kept forever (a MB per 50 000 messages). What is left after
    `parse_buffer` is at most one unfinished packet (< 280 bytes)."""
    if parser.buf_index:
        del parser.buf[: parser.buf_index]
        parser.buf_index = 0
