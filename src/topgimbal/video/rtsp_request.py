"""What an RTSP request says: the request as framed, its CSeq and Session headers, and what its
Transport header asks for (RFC 2326 12.39) once understood."""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass
from urllib.parse import urlsplit


class BadUrlError(ValueError):
    """A request URL that cannot be parsed (answered 400)."""


@dataclass
class Request:
    method: str
    url: str
    headers: dict[str, str]
    version: str = "RTSP/1.0"


def session_id(req: Request) -> str:
    return req.headers.get("session", "").split(";")[0].strip()


def url_path(url: str) -> str:
    """The path a request URL names (an absolute `rtsp://host[:port]/path` or a bare path).
    BadUrlError, with the reason, for what Python's URL parser refuses (an unterminated IPv6
    literal `[::1`, a stray `]`, characters NFKC turns into delimiters) or a bracketed host that
    is not an IPv6 address (checked here too: older Pythons let it through)."""
    if "://" not in url:
        return url
    try:
        parts = urlsplit(url)
    except ValueError as exc:
        raise BadUrlError(str(exc)) from None
    host = parts.netloc.rpartition("@")[2]
    if host.startswith("["):
        literal = host[1 : host.find("]")].partition("%")[0]
        try:
            ipaddress.IPv6Address(literal)
        except ValueError:
            raise BadUrlError(f"{literal!r} in brackets is not an IPv6 address") from None
    return parts.path


def cseq_ok(req: Request) -> bool:
    cseq = req.headers.get("cseq", "")
    return cseq.isascii() and cseq.isdigit() and len(cseq) <= 10


@dataclass(frozen=True)
class Transport:
    """What a SETUP's Transport header asks for, once understood: RTP over the RTSP connection
    (`tcp`, channels `rtp`/`rtcp`) or over UDP to the client's ports `rtp`/`rtcp`."""

    tcp: bool
    rtp: int
    rtcp: int

    def header(self) -> str:
        if self.tcp:
            return f"RTP/AVP/TCP;unicast;interleaved={self.rtp}-{self.rtcp}"
        return f"RTP/AVP;unicast;client_port={self.rtp}-{self.rtcp}"


def parse_transport(header: str, busy_channels: set[int] | frozenset[int] = frozenset()) -> Transport | None:
    """The first alternative of a Transport header (RFC 2326 12.39: comma-separated, in the
    client's order of preference) this server can serve: unicast RTP/AVP over TCP with
    interleaved channels 0..255 (the lowest free pair when not given), or over UDP with client
    ports 1..65535. None when there is none (the answer is 461)."""
    for alternative in header.split(","):
        opts = [o.strip() for o in alternative.split(";") if o.strip()]
        if not opts:
            continue
        profile = opts[0].upper()
        params: dict[str, str] = {}
        for o in opts[1:]:
            k, _, v = o.partition("=")
            params[k.strip().lower()] = v.strip()
        if profile not in ("RTP/AVP", "RTP/AVP/UDP", "RTP/AVP/TCP") or "multicast" in params:
            continue
        if profile == "RTP/AVP/TCP":
            if "interleaved" in params:
                pair = _number_pair(params["interleaved"], 0, 255)
            else:
                free = next(
                    (c for c in range(0, 255, 2) if c not in busy_channels and c + 1 not in busy_channels), None
                )
                pair = None if free is None else (free, free + 1)
            if pair is not None:
                return Transport(True, *pair)
        elif "client_port" in params:
            pair = _number_pair(params["client_port"], 1, 65535)
            if pair is not None:
                return Transport(False, *pair)
    return None


def _number_pair(text: str, lo: int, hi: int) -> tuple[int, int] | None:
    """N or N-M (digits) with both within lo..hi ("N" alone means N and N+1), else None."""
    first, sep, second = text.partition("-")
    if not sep:
        second = str(int(first) + 1) if first.isascii() and first.isdigit() and len(first) <= 5 else ""
    if not all(t.isascii() and t.isdigit() and len(t) <= 5 for t in (first, second)):
        return None
    a, b = int(first), int(second)
    return (a, b) if lo <= a <= hi and lo <= b <= hi else None
