"""`connect()` options, checked once, with the model profile's values where the caller gives none.

Every behaviour a model needs comes from its profile (`protocol.models.DeviceModel`): which motion
commands are echoed, how often a stop is sent, the pacing between commands, what a host keeps
sending. An option left at None takes the profile's value; an option given overrides it for this
connection (a device whose firmware differs from its profile)."""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TypedDict

from ..errors import FieldValueError
from ..protocol import CommandSpec, DeviceModel
from . import checks

log = logging.getLogger("topgimbal.client")


@dataclass(frozen=True)
class ClientOptions:
    timeout_s: float = 1.0  # per attempt
    retries: int = 2  # idempotent requests only
    signs: Mapping[str, int] | None = None  # per-axis sign overrides
    log_path: str | None = None  # JSONL traffic log
    echo_motion: bool | None = None  # None: the profile's `no_echo`; False: never wait for a motion echo
    combined_motion: bool | None = None  # False: one axis per frame (GAY + GAP rather than GAM)
    late_window_s: float | None = None  # None: max(2 s, 2 x timeout)
    dup_window_s: float = 0.05
    stop_repeats: int | None = None  # None: the profile's
    host_address: str | None = None  # None: the profile's (U on a serial line)
    link_timeout_s: float = 3.0
    reconnect_s: float | None = 1.0  # TCP / serial; None: do not reconnect
    min_command_gap_s: float | None = None  # None: the profile's pacing
    check_model: bool = True  # ask the device what it is on connect; warn on a mismatch
    host_feeds: bool = True  # keep sending what the profile's `host_feeds` names (C11: TIM, FAI)
    stream_renew_s: float | None = 20.0  # UDP: re-send a running stream's request at most this long apart

    def __post_init__(self) -> None:
        checks.positive_seconds("timeout_s", self.timeout_s, allow_none=False)
        checks.count("retries", self.retries, allow_none=False)
        checks.positive_seconds("late_window_s", self.late_window_s)
        checks.positive_seconds("dup_window_s", self.dup_window_s, allow_none=False, allow_zero=True)
        checks.positive_seconds("link_timeout_s", self.link_timeout_s, allow_none=False)
        checks.positive_seconds("reconnect_s", self.reconnect_s)
        checks.positive_seconds("min_command_gap_s", self.min_command_gap_s, allow_zero=True)
        checks.positive_seconds("stream_renew_s", self.stream_renew_s)
        checks.count("stop_repeats", self.stop_repeats, maximum=20)
        if self.stop_repeats == 0:
            raise FieldValueError("stop_repeats", 0, "1..20, or None for the model's")
        for name in ("echo_motion", "combined_motion"):
            flag = getattr(self, name)
            if flag is not None and not isinstance(flag, bool):
                raise FieldValueError(name, flag, "True, False or None (the model's)")
        for name in ("check_model", "host_feeds"):
            if not isinstance(getattr(self, name), bool):
                raise FieldValueError(name, getattr(self, name), "True or False")
        if self.log_path is not None and not isinstance(self.log_path, str):
            raise FieldValueError("log_path", self.log_path, "a file path (text) or None")
        if self.signs is not None and not isinstance(self.signs, Mapping):
            raise FieldValueError("signs", self.signs, "a mapping such as {'yaw': -1}")


class ConnectOptions(TypedDict, total=False):
    """The keyword options of `connect()`, `AsyncClient` and `Gimbal`, each as in `ClientOptions`
    (defaults there and in `ClientCore`)."""

    timeout_s: float
    retries: int
    signs: Mapping[str, int] | None
    log_path: str | None
    echo_motion: bool | None
    combined_motion: bool | None
    late_window_s: float | None
    dup_window_s: float
    stop_repeats: int | None
    host_address: str | None
    link_timeout_s: float
    reconnect_s: float | None
    min_command_gap_s: float | None
    check_model: bool
    host_feeds: bool
    stream_renew_s: float | None


class Behaviour:
    """What this connection does for its model: the profile, with the options' overrides."""

    def __init__(self, model: DeviceModel, options: ClientOptions) -> None:
        self.model = model
        self.options = options
        self.stop_repeats = options.stop_repeats or model.stop_repeats
        self.min_gap_s = model.min_command_gap_s if options.min_command_gap_s is None else options.min_command_gap_s
        self.combined = options.combined_motion is not False
        self._video_note_given = False

    def expects_echo(self, spec: CommandSpec) -> bool:
        """Whether a write of `spec` is acknowledged: the protocol's rule, the profile's `no_echo`
        (C13 motion), or the caller's `echo_motion` for motion commands."""
        if not spec.echo:
            return False
        if spec.motion and self.options.echo_motion is not None:
            return self.options.echo_motion
        return spec.ident not in self.model.no_echo

    def is_slow(self, spec: CommandSpec) -> bool:
        """A query the model may answer very late or never (C12 MOD)."""
        return spec.ident in self.model.slow_answers

    def note_camera_command(self, what: str) -> None:
        """Models whose camera commands act only once their video output has started (the C11's
        needs_video_output quirk) acknowledge them either way, so the acknowledgement cannot prove
        the photo or recording happened: say so, once per connection."""
        if self.model.quirks.get("needs_video_output") and not self._video_note_given:
            self._video_note_given = True
            log.warning(
                "%s: the %s acknowledges camera commands but acts on them only once its video output has "
                "started (a receiver playing its RTSP stream, e.g. cam.video_url()): start the video first, "
                "or the acknowledged %s may not have happened",
                what,
                self.model.name,
                what,
            )
