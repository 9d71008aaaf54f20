"""Packets: link layer -> IPv4/IPv6 -> UDP/TCP, taken apart and put together. Pure, no I/O.

`parse_packet()` accepts the link types a loopback or LAN capture has (Ethernet with VLAN tags,
Linux cooked v1/v2, BSD/macOS/Windows loopback, raw IP) and returns a `Segment`, or a string
saying why the packet carries no UDP/TCP payload we can use (never raises). The builders make
the packets our own captures hold: Ethernet (zero MAC addresses, as Linux `lo` captures show),
IPv4 or IPv6, UDP or TCP with correct checksums.
"""

from __future__ import annotations

import functools
import ipaddress
import struct
from typing import NamedTuple

from .pcapfile import (
    LINKTYPE_ETHERNET,
    LINKTYPE_IPV4,
    LINKTYPE_IPV6,
    LINKTYPE_LINUX_SLL,
    LINKTYPE_LINUX_SLL2,
    LINKTYPE_LOOP,
    LINKTYPE_NULL,
    LINKTYPE_RAW,
)

ETH_IPV4, ETH_IPV6 = 0x0800, 0x86DD
_VLAN_TAGS = (0x8100, 0x88A8, 0x9100)
_AF_INET6 = (10, 23, 24, 28, 30)  # Linux, Windows, NetBSD/OpenBSD, FreeBSD, macOS
_IPV6_EXTENSIONS = (0, 43, 60, 51)  # hop-by-hop, routing, destination options, AH
PROTO_TCP, PROTO_UDP = 6, 17
TCP_FIN, TCP_SYN, TCP_RST, TCP_PSH, TCP_ACK = 0x01, 0x02, 0x04, 0x08, 0x10

Endpoint = tuple[str, int]  # (IP address text, port)


class Segment(NamedTuple):
    """The transport payload of one packet."""

    transport: str  # "udp" or "tcp"
    src: Endpoint
    dst: Endpoint
    payload: bytes
    seq: int = 0  # TCP only
    flags: int = 0  # TCP only


def parse_packet(linktype: int, data: bytes) -> Segment | str | None:
    """The UDP/TCP segment in a captured packet; None for a packet that is simply something else
    (ARP, ICMP...); a string saying what is wrong with a packet that should have been usable."""
    try:
        ip = _network_layer(linktype, data)
        if ip is None or isinstance(ip, str):
            return ip
        return _ip(ip)
    except (struct.error, IndexError, ValueError) as exc:  # a header cut short
        return f"malformed packet: its {len(data)} bytes end inside a header ({exc})"


def _network_layer(linktype: int, data: bytes) -> bytes | str | None:
    if linktype == LINKTYPE_ETHERNET:
        etype, at = struct.unpack("!H", data[12:14])[0], 14
        while etype in _VLAN_TAGS:
            etype, at = struct.unpack("!H", data[at + 2 : at + 4])[0], at + 4
        return data[at:] if etype in (ETH_IPV4, ETH_IPV6) else None
    if linktype == LINKTYPE_LINUX_SLL:
        etype = struct.unpack("!H", data[14:16])[0]
        return data[16:] if etype in (ETH_IPV4, ETH_IPV6) else None
    if linktype == LINKTYPE_LINUX_SLL2:
        etype = struct.unpack("!H", data[0:2])[0]
        return data[20:] if etype in (ETH_IPV4, ETH_IPV6) else None
    if linktype in (LINKTYPE_NULL, LINKTYPE_LOOP):
        # NULL stores the address family in the capturing host's byte order: accept either.
        le, be = struct.unpack("<I", data[:4])[0], struct.unpack(">I", data[:4])[0]
        fams = (be,) if linktype == LINKTYPE_LOOP else (le, be)
        if any(f == 2 or f in _AF_INET6 for f in fams):
            return data[4:]
        return None
    if linktype in (LINKTYPE_RAW, 12, 14, LINKTYPE_IPV4, LINKTYPE_IPV6):
        return data
    return f"link type {linktype} is not supported (Ethernet, Linux cooked, loopback or raw IP are)"


def _ip(pkt: bytes) -> Segment | str | None:
    version = pkt[0] >> 4
    if version == 4:
        ihl = (pkt[0] & 0x0F) * 4
        total, frag, proto = struct.unpack("!H", pkt[2:4])[0], struct.unpack("!H", pkt[6:8])[0], pkt[9]
        if ihl < 20:
            return f"IPv4 header length {ihl} is below 20"
        if frag & 0x3FFF:  # more-fragments flag or a fragment offset
            return "IPv4 fragment (fragments are not reassembled)"
        src, dst = str(ipaddress.IPv4Address(pkt[12:16])), str(ipaddress.IPv4Address(pkt[16:20]))
        if total > len(pkt):
            return "IPv4 packet truncated (snap length?)"
        body = pkt[ihl:total] if total >= ihl else pkt[ihl:]  # 0: segmentation offload left it unset
    elif version == 6:
        plen, proto = struct.unpack("!H", pkt[4:6])[0], pkt[6]
        src, dst = str(ipaddress.IPv6Address(pkt[8:24])), str(ipaddress.IPv6Address(pkt[24:40]))
        if 40 + plen > len(pkt):
            return "IPv6 packet truncated (snap length?)"
        body = pkt[40 : 40 + plen]
        while proto in _IPV6_EXTENSIONS or proto == 44:
            if proto == 44:  # fragment header: only an atomic fragment (offset 0, no more) is whole
                if struct.unpack("!H", body[2:4])[0] & 0xFFF9:
                    return "IPv6 fragment (fragments are not reassembled)"
                proto, body = body[0], body[8:]
            else:
                n = (body[1] + 2) * 4 if proto == 51 else (body[1] + 1) * 8
                proto, body = body[0], body[n:]
    else:
        return f"IP version {version} is not 4 or 6"
    if proto == PROTO_UDP:
        sport, dport, ulen = struct.unpack("!HHH", body[:6])
        if ulen < 8 or ulen > len(body):
            return f"UDP length {ulen} does not fit the {len(body)}-byte payload"
        return Segment("udp", (src, sport), (dst, dport), bytes(body[8:ulen]))
    if proto == PROTO_TCP:
        sport, dport, seq = struct.unpack("!HHI", body[:8])
        off = (body[12] >> 4) * 4
        if off < 20 or off > len(body):
            return f"TCP header length {off} does not fit"
        return Segment("tcp", (src, sport), (dst, dport), bytes(body[off:]), seq, body[13])
    return None  # ICMP and the like


# -- building ----------------------------------------------------------------------------------


def _sum16(data: bytes) -> int:
    if len(data) % 2:
        data += b"\0"
    total = sum(struct.unpack(f"!{len(data) // 2}H", data))
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return total


def _checksum(data: bytes) -> int:
    return ~_sum16(data) & 0xFFFF


@functools.lru_cache(maxsize=256)
def _addr(text: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address:
    return ipaddress.ip_address(text)  # cached: the proxy writes a packet per chunk


def build_packet(
    transport: str,
    src: Endpoint,
    dst: Endpoint,
    payload: bytes,
    *,
    seq: int = 0,
    ack: int = 0,
    flags: int = TCP_PSH | TCP_ACK,
    ident: int = 0,
) -> bytes:
    """An Ethernet frame carrying `payload` from `src` to `dst` over UDP or TCP (IPv4 or IPv6 by
    the address), checksums filled in."""
    s, d = _addr(src[0]), _addr(dst[0])
    if s.version != d.version:
        raise ValueError(f"source {src[0]} and destination {dst[0]} are not the same IP version")
    proto = PROTO_UDP if transport == "udp" else PROTO_TCP
    if transport == "udp":
        l4 = struct.pack("!HHHH", src[1], dst[1], 8 + len(payload), 0) + payload
    elif transport == "tcp":
        l4 = struct.pack("!HHIIBBHHH", src[1], dst[1], seq & 0xFFFFFFFF, ack & 0xFFFFFFFF, 5 << 4, flags, 65535, 0, 0)
        l4 += payload
    else:
        raise ValueError(f"transport {transport!r} is not udp or tcp")
    if s.version == 4:
        pseudo = s.packed + d.packed + struct.pack("!BBH", 0, proto, len(l4))
    else:
        pseudo = s.packed + d.packed + struct.pack("!IxxxB", len(l4), proto)
    csum = _checksum(pseudo + l4)
    if transport == "udp":
        l4 = l4[:6] + struct.pack("!H", csum or 0xFFFF) + l4[8:]
    else:
        l4 = l4[:16] + struct.pack("!H", csum) + l4[18:]
    if s.version == 4:
        head = struct.pack(
            "!BBHHHBBH4s4s", 0x45, 0, 20 + len(l4), ident & 0xFFFF, 0x4000, 64, proto, 0, s.packed, d.packed
        )
        head = head[:10] + struct.pack("!H", _checksum(head)) + head[12:]
        etype = ETH_IPV4
    else:
        head = struct.pack("!IHBB16s16s", 6 << 28, len(l4), proto, 64, s.packed, d.packed)
        etype = ETH_IPV6
    return b"\0" * 12 + struct.pack("!H", etype) + head + l4
