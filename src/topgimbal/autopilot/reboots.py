"""Noticing that a MAVLink peer rebooted, so that what we remember of its past (the last image
capture sequence number) does not make us ignore its new orders: an autopilot counts its capture
sequence from 1 again after every boot.

A reboot is any of:
- its boot clock going back by more than BOOT_CLOCK_SLACK_MS (a reordered datagram is not a
  reboot), in what an autopilot always sends its gimbal: AUTOPILOT_STATE_FOR_GIMBAL_DEVICE
  `time_boot_us` (about 50 Hz, ArduPilot and PX4 alike), or SYSTEM_TIME `time_boot_ms` where
  that is streamed (ArduPilot does not on a gimbal's serial port by default);
- the connection it spoke on closing (a TCP or serial link; a UDP peer silent long enough to be
  forgotten) and the system being heard again: SITL's reboot re-opens its serial ports;
- a heartbeat gap longer than HEARTBEAT_GAP_S (heartbeats come at 1 Hz). A link outage that long
  counts too: after it, a sender that did not hear our ack has long given up retransmitting.
An autopilot reboots in less than HEARTBEAT_GAP_S, so the first two are what catches a reboot.

Pure logic with the time passed in; bounded (MAX_PEERS remembered, least recently heard goes)."""

from __future__ import annotations

import logging
from collections import OrderedDict, deque
from collections.abc import Callable, Hashable
from typing import TYPE_CHECKING

from ..links.base import link_peer

if TYPE_CHECKING:
    from ..links.mav import MAVLinkMessage

log = logging.getLogger("topgimbal.mavlink")

HEARTBEAT_GAP_S = 5.0
SAME_BOOT_S = 3.0  # further signs of a reboot this soon after one are the same reboot (logged once)
BOOT_CLOCK_SLACK_MS = 1000
MAX_PEERS = 64

RebootCallback = Callable[[int, str], None]  # (system id, why)


class RebootWatch:
    MESSAGES: tuple[str, ...] = (
        "HEARTBEAT",
        "SYSTEM_TIME",
        "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE",
    )  # what on_message reads (node.on)

    def __init__(self, on_reboot: RebootCallback, *, gap_s: float = HEARTBEAT_GAP_S) -> None:
        self.on_reboot = on_reboot
        self.gap_s = gap_s
        self._heartbeat: OrderedDict[tuple[int, int], float] = OrderedDict()
        self._boot_ms: OrderedDict[tuple[int, str], int] = OrderedDict()  # (system, message type)
        self._where: OrderedDict[int, Hashable] = OrderedDict()  # system -> (link, peer) last heard on
        self._closed: set[int] = set()  # systems whose connection closed since last heard
        self.reboots = 0
        self.history: deque[tuple[int, str]] = deque(maxlen=16)  # (system, why), the latest last
        self._noticed: OrderedDict[int, float] = OrderedDict()  # system -> when its last reboot was noticed
        self._now = 0.0

    def on_peer_gone(self, where: Hashable) -> None:
        """A connection closed (Node.on_peer_gone): the systems last heard on it, heard again,
        may have rebooted meanwhile."""
        for sysid, w in self._where.items():
            if w == where:
                self._closed.add(sysid)

    def on_message(self, m: MAVLinkMessage, now: float) -> None:
        self._now = now
        kind = m.get_type()
        sysid = m.get_srcSystem()
        where = link_peer(m)
        if where is not None:
            _remember(self._where, sysid, where)
        if sysid in self._closed:
            self._closed.discard(sysid)
            self._rebooted(sysid, "its connection closed and it is heard again")
        if kind == "HEARTBEAT":
            key = (m.get_srcSystem(), m.get_srcComponent())
            last = self._heartbeat.get(key)
            _remember(self._heartbeat, key, now)
            if last is not None and now - last > self.gap_s:
                self._rebooted(key[0], f"no heartbeat from {key[0]}/{key[1]} for {now - last:.1f} s")
        elif kind in ("SYSTEM_TIME", "AUTOPILOT_STATE_FOR_GIMBAL_DEVICE"):
            boot_ms = int(m.time_boot_ms) if kind == "SYSTEM_TIME" else int(m.time_boot_us) // 1000
            key = (sysid, kind)  # each message's own clock: a system's messages need not agree
            last_ms = self._boot_ms.get(key)
            _remember(self._boot_ms, key, boot_ms)
            if last_ms is not None and boot_ms + BOOT_CLOCK_SLACK_MS < last_ms:
                self._rebooted(sysid, f"its boot clock ({kind}) went back from {last_ms} ms to {boot_ms} ms")

    def _rebooted(self, sysid: int, why: str) -> None:
        last = self._noticed.get(sysid)
        _remember(self._noticed, sysid, self._now)
        if last is not None and self._now - last < SAME_BOOT_S:
            return  # one reboot shows several ways (its connection, each boot clock): noticed once
        self.reboots += 1
        self.history.append((sysid, why))
        log.info("system %d rebooted (%s): forgetting its capture sequence", sysid, why)
        self.on_reboot(sysid, why)


def _remember(table: OrderedDict, key: object, value: object) -> None:
    table[key] = value
    table.move_to_end(key)
    while len(table) > MAX_PEERS:
        table.popitem(last=False)
