"""`--cot-cert`, `--cot-key`, `--cot-ca`, `--cot-server-name`: the client certificate for `--cot tls://HOST:PORT` (a
TAK server's TLS streaming input), shared by `mavlink` and `zenoh --mavlink-keys`. The flags are the
CoT feature's (mavlink/features/cot.py); these names stay for the CLI modules that import them."""

from __future__ import annotations

import argparse
from typing import Any


def add_cot_tls_arguments(p: argparse.ArgumentParser) -> None:
    from ..mavlink.features.cot import add_tls_arguments

    add_tls_arguments(p)


def cot_tls(args: argparse.Namespace) -> Any:
    """A CotTls from the arguments, None when none is given (also for namespaces without them)."""
    from ..mavlink.features.cot import tls_from_args

    return tls_from_args(args)
