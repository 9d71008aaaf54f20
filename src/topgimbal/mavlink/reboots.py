"""Noticing that a MAVLink peer rebooted, so that what we remember of its past (the last image
capture sequence number) does not make us ignore its new orders: an autopilot counts its capture
sequence from 1 again after every boot.

A reboot is either of:
- its boot clock going back: SYSTEM_TIME `time_boot_ms` smaller than the last one heard by more
  than BOOT_CLOCK_SLACK_MS (a reordered datagram is not a reboot);
- a heartbeat gap longer than HEARTBEAT_GAP_S (heartbeats come at 1 Hz; an autopilot takes
  longer than this to boot). A link outage that long counts too: after it, a sender that did
  not hear our ack has long given up retransmitting.

Pure logic with the time passed in; bounded (MAX_PEERS remembered, least recently heard goes)."""

from __future__ import annotations

import logging
from collections import OrderedDict
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ._mav import MAVLinkMessage

log = logging.getLogger("topgimbal.mavlink")

HEARTBEAT_GAP_S = 5.0
BOOT_CLOCK_SLACK_MS = 1000
MAX_PEERS = 64

RebootCallback = Callable[[int, str], None]  # (system id, why)


class RebootWatch:
    def __init__(self, on_reboot: RebootCallback, *, gap_s: float = HEARTBEAT_GAP_S) -> None:
        self.on_reboot = on_reboot
        self.gap_s = gap_s
        self._heartbeat: OrderedDict[tuple[int, int], float] = OrderedDict()
        self._boot_ms: OrderedDict[int, int] = OrderedDict()
        self.reboots = 0

    def on_message(self, m: MAVLinkMessage, now: float) -> None:
        kind = m.get_type()
        if kind == "HEARTBEAT":
            key = (m.get_srcSystem(), m.get_srcComponent())
            last = self._heartbeat.get(key)
            _remember(self._heartbeat, key, now)
            if last is not None and now - last > self.gap_s:
                self._rebooted(key[0], f"no heartbeat from {key[0]}/{key[1]} for {now - last:.1f} s")
        elif kind == "SYSTEM_TIME":
            sysid = m.get_srcSystem()
            boot_ms = int(m.time_boot_ms)
            last_ms = self._boot_ms.get(sysid)
            _remember(self._boot_ms, sysid, boot_ms)
            if last_ms is not None and boot_ms + BOOT_CLOCK_SLACK_MS < last_ms:
                self._rebooted(sysid, f"its boot clock went back from {last_ms} ms to {boot_ms} ms")

    def _rebooted(self, sysid: int, why: str) -> None:
        self.reboots += 1
        log.info("system %d rebooted (%s): forgetting its capture sequence", sysid, why)
        self.on_reboot(sysid, why)


def _remember(table: OrderedDict, key: object, value: object) -> None:  # type: ignore[type-arg]
    table[key] = value
    table.move_to_end(key)
    while len(table) > MAX_PEERS:
        table.popitem(last=False)
