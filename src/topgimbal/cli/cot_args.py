"""`--cot-cert`, `--cot-key`, `--cot-ca`, `--cot-server-name`: the client certificate for `--cot tls://HOST:PORT` (a
TAK server's TLS streaming input), shared by `mavlink` and `zenoh --mavlink-keys`."""

from __future__ import annotations

import argparse
from typing import Any


def add_cot_tls_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--cot-cert", metavar="PEM", help="with --cot tls://: the client certificate the TAK server asks for"
    )
    p.add_argument("--cot-key", metavar="PEM", help="with --cot tls://: the client certificate's private key")
    p.add_argument("--cot-ca", metavar="PEM",
                   help="with --cot tls://: the CA that signed the TAK server's certificate (default: the system's)")  # fmt: skip
    p.add_argument("--cot-server-name", metavar="NAME",
                   help="with --cot tls://: the name the TAK server's certificate carries when not the URL's host")  # fmt: skip


def cot_tls(args: argparse.Namespace) -> Any:
    """A CotTls from the arguments, None when none is given (also for namespaces without them)."""
    cert, key, ca, name = (getattr(args, f"cot_{n}", None) for n in ("cert", "key", "ca", "server_name"))
    if not (cert or key or ca or name):
        return None
    from ..outputs.cot_stream import CotTls

    return CotTls(cert, key, ca, name)
