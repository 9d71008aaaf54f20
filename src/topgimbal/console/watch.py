"""`topgimbal console --proxy`: the console watches a proxy (`topgimbal.wire.proxy.Proxy`) that sits
between a ground station (or vendor app) and a camera, in this process.

Read-only by design: the camera belongs to whoever talks to it through the proxy; a second
controller injecting frames into their session would move a gimbal under them and could confuse
its request matching. So the page shows what crosses the proxy (the traffic pane, both directions
and every client, the attitude read from the frames that pass, the proxy's counters) and every
control that would send to the camera is disabled with the reason; an op sent anyway is refused
with kind `readonly`. The pcap download holds what passed, each frame with its client's address.
"""

from __future__ import annotations

import contextlib
import logging
from collections import OrderedDict
from typing import Any

from ..clock import wall_time
from ..protocol import DeviceModel, Diagnostic, Dialect, Frame, Message
from ..protocol.signs import flip, resolve_signs
from ..wire.packets import Endpoint
from ..wire.proxy import Proxy, ProxyEvent
from .capture import Link, link_for
from .ops import OpArgs, ReadOnlyError
from .pages import PageHub

log = logging.getLogger(__name__)

MAX_CLIENTS_SHOWN = 16  # the proxy's clients listed on the page (the most recently heard)


def client_endpoint(label: str) -> Endpoint | None:
    """("127.0.0.1", 53012) from a proxy client label "udp 127.0.0.1:53012" (None for serial)."""
    kind, _, where = label.partition(" ")
    host, sep, port = where.rpartition(":")
    if kind not in ("udp", "tcp") or not sep or not port.isdigit():
        return None
    return host.strip("[]"), int(port)


def proxy_link(proxy: Proxy, model: DeviceModel) -> Link:
    link = link_for(proxy.to.text, model)
    if proxy.to.scheme == "serial" and proxy.listen.scheme == "tcp":
        return Link("tcp", link.host, link.device)
    return link


class WatchHub(PageHub):
    mode = "watch"

    def __init__(
        self,
        proxy: Proxy,
        dialect: Dialect,
        model: DeviceModel,
        *,
        attitude_hz: float = 50.0,
    ) -> None:
        url = f"{proxy.url} -> {proxy.to.text}"
        super().__init__(dialect=dialect, model=model, url=url, link=proxy_link(proxy, model))
        self.proxy = proxy
        self.attitude_hz = min(max(attitude_hz, 1.0), 50.0)
        self._signs = resolve_signs(model)
        self._attitude_at = 0.0
        self.clients: OrderedDict[str, float] = OrderedDict()  # label -> last frame (wall clock)

    @property
    def readonly(self) -> str:
        return (
            f"this console watches the proxy {self.proxy.url} -> {self.proxy.to.text} and sends nothing to "
            "the camera: the proxy's clients control it"
        )

    async def start(self) -> None:
        self._unsubscribe.append(self.proxy.subscribe(self._on_event))
        await super().start()

    def _on_event(self, event: ProxyEvent) -> None:
        item = event.item
        if isinstance(item, Diagnostic):
            self.note(event.direction, item.raw, f"{item.kind}: {item.detail}", t=event.t, client=event.client)
            return
        self._seen(event.client, event.t)
        ident = item.ident
        self.record(
            event.direction,
            item,
            event.message,
            t=event.t,
            host=client_endpoint(event.client),
            client=event.client,
        )
        if event.direction == "in" and ident in self.streams and event.message is not None:
            self._attitude(item, event.message, event.t)

    def _attitude(self, frame: Frame, message: Message, t: float) -> None:
        """Push the attitude a passing report carries (API signs), at most attitude_hz a second."""
        if message.spec is None or not message.fields or t - self._attitude_at < 1.0 / self.attitude_hz:
            return
        values = flip(message.spec, message.fields, self._signs)
        with contextlib.suppress(KeyError, TypeError, ValueError):
            att = {axis: float(values[f"{axis}_deg"]) for axis in ("yaw", "pitch", "roll")}
            self._attitude_at = t
            self.broadcast({"type": "attitude", **att, "t": t}, essential=False)

    def status(self) -> dict[str, Any]:
        stats = self.proxy.stats.as_dict()
        age = None if self.last_in is None else wall_time() - self.last_in
        return {
            **super().status(),
            "link": "watching",
            "link_reason": self.readonly,
            "readonly": self.readonly,
            "stats": {"frames_in": stats["frames_in"], "frames_out": stats["frames_out"], **stats},
            "last_in": self.last_in,
            "silent_s": age,
            "proxy": {"listen": self.proxy.url, "to": self.proxy.to.text, "clients": self._clients()},
        }

    def _seen(self, client: str, t: float) -> None:
        self.clients[client] = t
        self.clients.move_to_end(client)
        while len(self.clients) > MAX_CLIENTS_SHOWN:
            self.clients.popitem(last=False)

    def _clients(self) -> list[dict[str, Any]]:
        return [{"client": c, "last_s_ago": round(wall_time() - t, 1)} for c, t in self.clients.items()]

    def hello(self) -> dict[str, Any]:
        return {**super().hello(), "attitude_hz": self.attitude_hz, "readonly": self.readonly}

    async def carry_out(self, op: str, msg: OpArgs) -> object:
        raise ReadOnlyError(self.readonly)


__all__ = ["WatchHub", "client_endpoint"]
