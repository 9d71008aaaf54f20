"""The bridge's configuration: BridgeConfig (what `topgimbal mavlink`'s flags fill, field by field:
cli/config_args.py copies them from each field's `flag`), its checks, and the ids and roles it allows."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from ..errors import TopGimbalError
from ..links.endpoints import MAX_PEERS, parse_endpoint
from ..outputs.cot_stream import CotTls
from ..outputs.rtp_out import VideoOutError, parse_targets

ROLES = ("device", "manager", "both")
GIMBAL_COMPIDS = (154, 171, 172, 173, 174, 175)  # MAV_COMP_ID_GIMBAL, GIMBAL2..6
CAMERA_COMPIDS = (100, 101, 102, 103, 104, 105)  # MAV_COMP_ID_CAMERA..CAMERA6


class BridgeConfigError(TopGimbalError, ValueError):
    pass


def cli(
    flag: str, convert: Callable[[Any], Any] | None = None, *, from_args: Callable[[Any], Any] | None = None
) -> dict[str, Any]:
    """A field's flag on `topgimbal mavlink`, as the field's metadata: cli/config_args.py fills the
    field from that flag's value (through `convert`), or from `from_args(namespace)` when several
    flags make it; errors that name the field are told with the flag."""
    return {"flag": flag, "convert": convert, "from_args": from_args}


def _or(default: Any) -> Callable[[Any], Any]:
    return lambda v: default if v is None else v


def _not(v: Any) -> bool:
    return not v


def _off_is_none(v: str | None) -> str | None:
    return None if v == "off" else v


def _camera_compid(args: Any) -> int | None:
    if getattr(args, "no_camera", False):
        return None
    given = getattr(args, "camera_compid", None)
    return 100 if given is None else int(given)


def _feature_options(args: Any) -> dict[str, Any]:
    from .features import FEATURES

    out = {}
    for spec in FEATURES:
        value = spec.from_args(args) if spec.from_args is not None else None
        if value is not None:
            out[spec.name] = value
    return out


def _feature_flags() -> dict[str, str]:
    """{feature name: its first flag} for the features kept in `features` (errors name the flag)."""
    import argparse

    from .features import FEATURES

    out = {}
    for spec in FEATURES:
        if spec.from_args is not None:
            p = argparse.ArgumentParser(add_help=False)
            spec.add_arguments(p)
            out[spec.name] = next(a.option_strings[0] for a in p._actions if a.option_strings)
    return out


def _cot_tls(args: Any) -> CotTls | None:
    from .features.cot import tls_from_args

    return tls_from_args(args)


@dataclass
class BridgeConfig:
    url: str
    model: str
    endpoints: list[str] = field(metadata=cli("--mavlink", list))
    sysid: int = field(default=1, metadata=cli("--sysid"))
    compid: int = field(default=154, metadata=cli("--compid", _or(154)))
    # None: no camera components
    camera_compid: int | None = field(default=100, metadata=cli("--camera-compid", from_args=_camera_compid))
    # a second camera component for the thermal lens, where the model has one
    thermal: bool = field(default=True, metadata=cli("--no-thermal", _not))
    role: str = field(default="both", metadata=cli("--role"))
    attitude_hz: float = field(default=20.0, metadata=cli("--attitude-hz"))
    stream_hz: float = field(default=50.0, metadata=cli("--stream-hz"))
    heartbeat_hz: float = 1.0
    range_hz: float = field(default=1.0, metadata=cli("--range-hz"))
    # None: the model's streams at the camera's address
    video_urls: list[str] | None = field(default=None, metadata=cli("--video-url"))
    # the first stream's RTSP port when not the profile's (others keep the spacing)
    video_port: int | None = field(default=None, metadata=cli("--video-port"))
    # "[LENS=]udp://HOST:PORT": the lens's stream pushed as RTP (rtp_out.py)
    video_out: list[str] | None = field(default=None, metadata=cli("--video-out"))
    # the camera's files over HTTP (sim --media-port): CAMERA_IMAGE_CAPTURED.file_url
    media_url: str | None = field(default=None, metadata=cli("--media-url"))
    # track commands run topgimbal.track on a model without a tracker
    companion_tracking: bool = field(default=False, metadata=cli("--companion-tracking"))
    timeout_s: float = field(default=1.0, metadata=cli("--timeout"))
    retries: int = 2
    silence_s: float = field(default=3.0, metadata=cli("--silence"))
    max_peers: int = field(default=MAX_PEERS, metadata=cli("--max-peers"))
    # MAVLink 2 signing (signing.py): sign all, accept only signed
    signing_key: bytes | None = field(default=None, metadata=cli("--signing-key"))
    client_options: dict[str, Any] = field(default_factory=dict)
    # HOST:PORT serving the camera definitions; None: not served
    definition_http: str | None = field(default="127.0.0.1:0", metadata=cli("--definition-http", _off_is_none))
    # a GeoTIFF DEM: CAMERA_FOV_STATUS's image centre on it (else flat at home)
    terrain: str | None = field(default=None, metadata=cli("--terrain"))
    # udp:// tcp:// tls://HOST:PORT: Cursor-on-Target of what the camera looks at (cot.py)
    cot: str | None = field(default=None, metadata=cli("--cot"))
    # tls://: the client certificate, key and CA (cot_stream.py)
    cot_tls: CotTls | None = field(default=None, metadata=cli("--cot-cert", from_args=_cot_tls))
    cot_name: str | None = None  # the camera's name in its CoT uid/callsign (several cameras on one system)
    # DIR: the camera's video as MPEG-TS with MISB ST 0601 KLV (klv_record.py)
    record: str | None = field(default=None, metadata=cli("--record"))
    # the options of features without a field of their own, {name: value} (features/: each spec's
    # `from_args` fills its entry from its flags)
    features: Mapping[str, Any] = field(
        default_factory=dict,
        metadata={"flag": None, "convert": None, "from_args": _feature_options, "named_flags": _feature_flags},
    )

    # a CAMERA_INFORMATION naming the HTTP definition waits while another definition downloads
    # (camdef/pacing.py: MAVSDK 4.1 deadlocks otherwise); False: answered at once
    definition_one_at_a_time: bool = field(default=True, metadata=cli("--definition-all-at-once", _not))
    # the host written into the definition URI (advertise.py); None: found
    definition_host: str | None = field(default=None, metadata=cli("--definition-host"))
    # ask the autopilot for GLOBAL_POSITION_INT and SYSTEM_TIME (autopilot/streams.py)
    request_streams: bool = field(default=True, metadata=cli("--no-request-streams", _not))

    def definition_address(self) -> tuple[str, int] | None:
        if not self.definition_http:
            return None
        host, sep, port = self.definition_http.rpartition(":")
        if not sep or not port.isdigit() or not 0 <= int(port) <= 65535:
            raise BridgeConfigError(f"definition_http={self.definition_http!r}: expected HOST:PORT (port 0..65535)")
        return host.strip("[]") or "127.0.0.1", int(port)

    def check(self, need_endpoints: bool = True) -> None:
        """`need_endpoints` False: the links come from elsewhere (a shared node's, zenoh_link.py)."""
        if need_endpoints and not self.endpoints:
            raise BridgeConfigError("endpoints: at least one MAVLink endpoint is needed, e.g. udpout:HOST:PORT")
        for e in self.endpoints:
            parse_endpoint(e)
        if self.role not in ROLES:
            raise BridgeConfigError(f"role {self.role!r}: expected one of {', '.join(ROLES)}")
        if not 1 <= self.sysid <= 255:
            raise BridgeConfigError(f"system id {self.sysid}: expected 1..255")
        if self.compid not in GIMBAL_COMPIDS:
            raise BridgeConfigError(f"gimbal component id {self.compid}: expected one of {GIMBAL_COMPIDS}")
        allowed = CAMERA_COMPIDS[:-1] if self.thermal else CAMERA_COMPIDS  # the thermal lens takes the next id
        if self.camera_compid is not None and self.camera_compid not in allowed:
            raise BridgeConfigError(f"camera component id {self.camera_compid}: expected one of {allowed}")
        for name, lo, hi in (("attitude_hz", 0.0, 100.0), ("stream_hz", 1.0, 100.0), ("heartbeat_hz", 0.1, 10.0),
                             ("range_hz", 0.0, 10.0), ("silence_s", 0.2, 60.0), ("timeout_s", 0.05, 30.0)):  # fmt: skip
            v = getattr(self, name)
            if not lo <= v <= hi:
                raise BridgeConfigError(f"{name}={v:g}: expected {lo:g}..{hi:g}")
        if self.video_port is not None and not 1 <= self.video_port <= 65535:
            raise BridgeConfigError(f"video_port={self.video_port}: expected 1..65535")
        try:
            parse_targets(self.video_out)
        except VideoOutError as exc:
            raise BridgeConfigError(str(exc)) from None
        if self.signing_key is not None and len(self.signing_key) != 32:
            raise BridgeConfigError(f"signing_key: {len(self.signing_key)} bytes, expected 32")
        self.definition_address()
        if self.media_url is not None and not self.media_url.startswith(("http://", "https://")):
            raise BridgeConfigError(
                f"media_url {self.media_url!r}: expected http://HOST:PORT/ (sim --media-port prints it)"
            )
        if not 1 <= self.max_peers <= 256:
            raise BridgeConfigError(f"max_peers={self.max_peers}: expected 1..256")
        from .features import FEATURES  # each attached feature checks its own options

        unknown = sorted(set(self.features) - {s.name for s in FEATURES if s.from_args is not None})
        if unknown:
            known = ", ".join(s.name for s in FEATURES if s.from_args is not None) or "none"
            raise BridgeConfigError(f"features: unknown feature {unknown[0]!r} (these take options here: {known})")
        for spec in FEATURES:
            spec.check(self)
