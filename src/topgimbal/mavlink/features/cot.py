"""`--cot URL`: Cursor-on-Target (TAK) of what the first camera looks at, once a second
(outputs/cot.py sends it; this attaches it to the bridge's sighting port)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .base import BridgeContext, BridgeOptions, FeatureSpec, SightingOutput

if TYPE_CHECKING:  # loaded when a bridge is made: the flags alone keep `topgimbal --help` light
    from ...outputs.cot import CotSender
    from ...outputs.cot_stream import CotTls
    from ...outputs.sighting import Sighting


@dataclass(frozen=True)
class CotConfig:
    url: str
    tls: CotTls | None
    name: str | None  # the camera's name in its uid / callsign (several cameras on one system)


class CotFeature(SightingOutput):
    name = "cot"

    def __init__(self, config: CotConfig) -> None:
        super().__init__()
        self.config = config
        self.sender: CotSender | None = None

    def build(self, ctx: BridgeContext, source: Callable[[], Sighting | None]) -> CotSender:
        from ...outputs.cot import CotSender, cot_names

        uid, callsign = cot_names(ctx.sysid, ctx.model, self.config.name)
        self.sender = CotSender(self.config.url, source, uid=uid, callsign=callsign, tls=self.config.tls)
        return self.sender


def make(c: BridgeOptions) -> CotFeature | None:
    return CotFeature(CotConfig(c.cot, c.cot_tls, c.cot_name)) if c.cot is not None else None


def check(c: BridgeOptions) -> None:
    from ...outputs.cot import check_config

    check_config(c.cot, c.cot_tls, c.video_urls)  # CotConfigError: the target, its files, the URLs


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--cot", metavar="URL",
                   help="send Cursor-on-Target (TAK) of the camera's view and target at 1 Hz: udp://HOST:PORT (TAK's "
                   "mesh, e.g. udp://239.2.3.1:6969), tcp://HOST:PORT or tls://HOST:PORT (a TAK server's streaming "
                   "input, e.g. 8087 / 8089; reconnected when lost)")  # fmt: skip
    add_tls_arguments(p)


def add_tls_arguments(p: argparse.ArgumentParser) -> None:
    """`--cot-cert`, `--cot-key`, `--cot-ca`, `--cot-server-name` (also `zenoh --mavlink-keys`'s)."""
    p.add_argument(
        "--cot-cert", metavar="PEM", help="with --cot tls://: the client certificate the TAK server asks for"
    )
    p.add_argument("--cot-key", metavar="PEM", help="with --cot tls://: the client certificate's private key")
    p.add_argument("--cot-ca", metavar="PEM",
                   help="with --cot tls://: the CA that signed the TAK server's certificate (default: the system's)")  # fmt: skip
    p.add_argument("--cot-server-name", metavar="NAME",
                   help="with --cot tls://: the name the TAK server's certificate carries when not the URL's host")  # fmt: skip


def tls_from_args(args: Any) -> CotTls | None:
    """A CotTls from the arguments, None when none is given (also for namespaces without them)."""
    cert, key, ca, name = (getattr(args, f"cot_{n}", None) for n in ("cert", "key", "ca", "server_name"))
    if not (cert or key or ca or name):
        return None
    from ...outputs.cot_stream import CotTls

    return CotTls(cert, key, ca, name)


SPEC = FeatureSpec("cot", make, check, add_arguments)
