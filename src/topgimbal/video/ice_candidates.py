"""Which of a browser's ICE candidates the console may send connectivity checks (STUN) to.

A WHEP offer lists every address the browser's host has (other interfaces, VPNs, mDNS names
`x.local`) and anything a token holder writes into it (169.254.169.254, 8.8.8.8, a multicast
group): aioice would send STUN to each. The console offers one host candidate, the address the
browser reached it on (webrtc.py), so only candidates on that address's own network can ever
answer: those are kept, every other line `a=candidate:` is dropped (loopback: loopback only)."""

from __future__ import annotations

import ipaddress
import logging

log = logging.getLogger("topgimbal.video.webrtc")

Network = ipaddress.IPv4Network | ipaddress.IPv6Network


def _address(text: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
    try:
        return ipaddress.ip_address(text.strip("[]").split("%", 1)[0])
    except ValueError:  # a name (x.local): resolving it would be a multicast query
        return None


def _is_loopback(address: str) -> bool:
    a = _address(address)
    return a.is_loopback if a is not None else address == "localhost"


def own_networks(host: str) -> list[Network]:
    """The networks of the console's interface that holds `host` (from the interfaces' prefixes;
    loopback: 127.0.0.0/8 and ::1). None found (an address no interface has): no network."""
    a = _address(host)
    if a is None:
        return []
    if a.is_loopback:
        return [ipaddress.ip_network("127.0.0.0/8"), ipaddress.ip_network("::1/128")]
    import ifaddr  # aioice's own dependency: there whenever WebRTC is

    out: list[Network] = []
    for adapter in ifaddr.get_adapters():
        for ip in adapter.ips:
            text = ip.ip if isinstance(ip.ip, str) else ip.ip[0]
            if _address(text) == a:
                out.append(ipaddress.ip_network(f"{text.split('%', 1)[0]}/{ip.network_prefix}", strict=False))
    return out


def reachable(candidate_address: str, networks: list[Network]) -> bool:
    """A unicast address on one of `networks` (not multicast, not unspecified, not a name)."""
    a = _address(candidate_address)
    if a is None or a.is_multicast or a.is_unspecified:
        return False
    return any(a in n for n in networks if n.version == a.version)


def remote_candidates(offer_sdp: str, host: str | None) -> str:
    """The offer with only the browser's candidates on the console's own network (the network of
    `host`, the address the browser reached it on). A console reached on loopback checks only
    loopback candidates; one reached on a LAN address only that LAN's."""
    if host is None:
        return offer_sdp  # no socket to read the address from (not over HTTP): aioice's own choice
    networks = own_networks(host)
    kept, dropped = [], 0
    for line in offer_sdp.splitlines():
        if line.startswith("a=candidate:"):
            parts = line.split()
            if len(parts) < 5 or not reachable(parts[4], networks):
                dropped += 1
                continue
        kept.append(line)
    if dropped:
        log.debug("webrtc: %d candidates of an offer are not on %s's network: dropped", dropped, host)
    return "\r\n".join(kept) + "\r\n"
