"""CoT over a TAK server's streaming inputs on loopback: tcp:// and mutual-TLS tls:// (a throwaway
CA, server and client certificates made here with cryptography), read by a receiver built on
pytak's own stream reader (RXWorker.readcot: the event framing TAK clients use) and every event
parsed by takproto; a server that goes away and comes back gets the newest events kept, the
older ones dropped and counted, with one log line for the loss and one for the return."""

from __future__ import annotations

import asyncio
import datetime
import itertools
import logging
import ssl
from pathlib import Path
from typing import Any

import pytak
import pytest
import takproto
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID

from topgimbal.geo import Fix as GeoFix
from topgimbal.outputs.cot import CotConfigError, CotSender, CotTls, Sighting
from topgimbal.outputs.cot_stream import StreamOut, open_out, parse_url

from .conftest import eventually

pytestmark = pytest.mark.loopback

LAT, LON = 47.0, 8.0


class _Rx(pytak.RXWorker):
    async def handle_data(self, data: bytes) -> None:  # pragma: no cover - readcot() is called directly
        pass


class TakReader:
    """A TAK server's streaming input as far as a client sees it: accepts, reads events with pytak."""

    def __init__(self, ctx: ssl.SSLContext | None = None) -> None:
        self.ctx = ctx
        self.events: list[Any] = []  # takproto's parse of each
        self.raw: list[bytes] = []
        self.peers: list[Any] = []
        self.server: asyncio.Server | None = None
        self.port = 0
        self._conns: list[asyncio.StreamWriter] = []

    async def start(self, port: int = 0) -> TakReader:
        self.server = await asyncio.start_server(self._serve, "127.0.0.1", port, ssl=self.ctx)
        self.port = self.server.sockets[0].getsockname()[1]
        return self

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self._conns.append(writer)
        self.peers.append(writer.get_extra_info("peercert"))
        rx = _Rx(asyncio.Queue(), {"TAK_PROTO": "0"}, reader)
        try:
            while (data := await rx.readcot()) is not None:
                self.raw.append(data)
                self.events.append(takproto.parse_proto(bytearray(data)))
        except (ConnectionError, ssl.SSLError, asyncio.LimitOverrunError):
            pass

    async def stop(self) -> None:
        assert self.server is not None
        self.server.close()
        for w in self._conns:
            w.close()
        self._conns.clear()
        await self.server.wait_closed()


def _sighting() -> Sighting:
    target = GeoFix(LAT + 0.002, LON, 500.0, 250.0, "flat", 4.0, 0.0, -30.0)  # type: ignore[arg-type]
    return Sighting(LAT, LON, 650.0, 30.0, -30.0, 0.0, 60.0, 34.0, target, [], "rtsp://127.0.0.1:8554/main")


async def _run(sender: CotSender, until: Any) -> None:
    task = asyncio.ensure_future(sender.run())
    try:
        await eventually(until, timeout=20.0, what="CoT events over the stream")
    finally:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)


async def test_tcp_stream_reaches_a_pytak_reader_event_by_event() -> None:
    rx = await TakReader().start()
    sender = CotSender(f"tcp://127.0.0.1:{rx.port}", _sighting, uid="topgimbal-C12-1", callsign="C12 1", rate_hz=20)
    try:
        await _run(sender, lambda: len(rx.events) >= 10)
    finally:
        await rx.stop()
    assert all(m is not None for m in rx.events)
    types = [m.cotEvent.type for m in rx.events]
    assert types[:2] == ["a-f-A-M-F-Q", "b-m-p-s-p-i"] and set(types) == {"a-f-A-M-F-Q", "b-m-p-s-p-i"}
    vehicle = rx.events[0].cotEvent
    assert (vehicle.uid, vehicle.lat, vehicle.lon) == ("topgimbal-C12-1", LAT, LON)
    assert vehicle.hae > 650.0  # MSL plus the geoid's ~48 m here (test_cot_xml.py checks the value)


def _event(i: int) -> bytes:
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<event version="2.0" uid="e{i}" type="a-f-A-M-F-Q" how="m-g" '
            'time="2026-01-01T00:00:00Z" start="2026-01-01T00:00:00Z" stale="2026-01-01T00:01:00Z">'
            f'<point lat="{LAT}" lon="{LON}" hae="0" ce="1" le="1"/><detail/></event>').encode()  # fmt: skip


async def test_a_lost_server_gets_the_newest_events_when_it_is_back(caplog: pytest.LogCaptureFixture) -> None:
    rx = await TakReader().start()
    out = open_out(f"tcp://127.0.0.1:{rx.port}")
    assert isinstance(out, StreamOut) and out.queue.maxlen == 30
    task = asyncio.ensure_future(out.run())
    try:
        with caplog.at_level(logging.INFO, "topgimbal.mavlink"):
            for i in range(5):
                out.offer(_event(i))
            await eventually(lambda: len(rx.events) == 5, timeout=20.0)
            await rx.stop()
            await eventually(lambda: not out.connected, timeout=20.0, what="the loss seen")
            for i in range(5, 55):  # 50 while the server is away: the newest 30 kept, 20 dropped
                out.offer(_event(i))
            assert out.dropped == 20 and len(out.queue) == 30
            rx.events.clear()
            await rx.start(rx.port)  # the same address, as a restarted server
            await eventually(lambda: len(rx.events) == 30, timeout=30.0, what="the kept events after the return")
        assert [m.cotEvent.uid for m in rx.events] == [f"e{i}" for i in range(25, 55)]
        assert out.connects == 2 and out.sent == 35
        assert "connection lost (closed by the server)" in caplog.text
        assert "connected again after" in caplog.text and "30 events kept to send, 20 dropped meanwhile" in caplog.text
    finally:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        await rx.stop()


async def test_a_server_that_drops_every_connection_at_once_is_tried_ever_more_slowly() -> None:
    closed: list[float] = []

    async def hang_up(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        closed.append(asyncio.get_running_loop().time())
        writer.close()

    server = await asyncio.start_server(hang_up, "127.0.0.1", 0)
    out = open_out(f"tcp://127.0.0.1:{server.sockets[0].getsockname()[1]}")
    task = asyncio.ensure_future(out.run())
    try:
        await asyncio.sleep(7.0)  # 1 s apart: 7 or 8 connections; doubling from 2 s: 3
    finally:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        server.close()
    assert 1 <= len(closed) <= 4, closed
    gaps = [b - a for a, b in itertools.pairwise(closed)]
    assert all(later > earlier for earlier, later in itertools.pairwise(gaps)), gaps


async def test_offer_never_waits_for_a_server_that_is_not_there() -> None:
    out = open_out("tcp://127.0.0.1:9")  # discard: nothing listens on loopback here
    assert isinstance(out, StreamOut)
    task = asyncio.ensure_future(out.run())
    try:
        for i in range(1000):
            out.offer(_event(i))  # synchronous: queued, the bridge goes on
        await asyncio.sleep(0.2)
        assert len(out.queue) == 30 and out.dropped == 970 and not out.connected
    finally:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)


# -- mutual TLS ----------------------------------------------------------------------------------


def _cert(name: str, key: Any, issuer: tuple[x509.Name, Any] | None, *, ca: bool = False) -> x509.Certificate:
    now = datetime.datetime.now(datetime.timezone.utc)
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
    issuer_name, issuer_key = issuer or (subject, key)
    b = (x509.CertificateBuilder().subject_name(subject).issuer_name(issuer_name).public_key(key.public_key())
         .serial_number(x509.random_serial_number()).not_valid_before(now - datetime.timedelta(minutes=5))
         .not_valid_after(now + datetime.timedelta(days=1))
         .add_extension(x509.BasicConstraints(ca=ca, path_length=None), critical=True))  # fmt: skip
    if not ca:
        import ipaddress

        b = b.add_extension(x509.SubjectAlternativeName([x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]), False)
    return b.sign(issuer_key, hashes.SHA256())


def _write(path: Path, cert: x509.Certificate, key: Any) -> tuple[str, str]:
    path.with_suffix(".crt").write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    path.with_suffix(".key").write_bytes(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                                           serialization.NoEncryption()))  # fmt: skip
    return str(path.with_suffix(".crt")), str(path.with_suffix(".key"))


@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    d = tmp_path_factory.mktemp("pki")
    out = {}
    for label in ("ca", "other_ca"):
        k = ec.generate_private_key(ec.SECP256R1())
        c = _cert(f"topgimbal test {label}", k, None, ca=True)
        out[label], out[f"{label}_key"] = _write(d / label, c, k)
        out[f"{label}_obj"] = (c, k)  # type: ignore[assignment]
    ca_cert, ca_key = out["ca_obj"]  # type: ignore[misc]
    for label in ("server", "client"):
        k = ec.generate_private_key(ec.SECP256R1())
        out[label], out[f"{label}_key"] = _write(d / label, _cert(f"tak-{label}", k, (ca_cert.subject, ca_key)), k)
    return out


def _server_ctx(pki: dict[str, str]) -> ssl.SSLContext:
    ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH, cafile=pki["ca"])
    ctx.verify_mode = ssl.CERT_REQUIRED  # a TAK server's 8089: no client certificate, no stream
    ctx.load_cert_chain(pki["server"], pki["server_key"])
    return ctx


async def test_tls_with_a_client_certificate_reaches_the_reader(pki: dict[str, str]) -> None:
    rx = await TakReader(_server_ctx(pki)).start()
    tls = CotTls(pki["client"], pki["client_key"], pki["ca"])
    sender = CotSender(f"tls://127.0.0.1:{rx.port}", _sighting, uid="topgimbal-SIP-1", callsign="SIP 1",
                       rate_hz=20, tls=tls)  # fmt: skip
    try:
        await _run(sender, lambda: len(rx.events) >= 10)
    finally:
        await rx.stop()
    assert all(m is not None for m in rx.events)
    assert {m.cotEvent.uid for m in rx.events} == {"topgimbal-SIP-1", "topgimbal-SIP-1.SPI"}
    subject = dict(x[0] for x in rx.peers[0]["subject"])
    assert subject["commonName"] == "tak-client"  # the server saw our client certificate


async def test_tls_refuses_a_server_its_ca_did_not_sign(pki: dict[str, str], caplog: pytest.LogCaptureFixture) -> None:
    rx = await TakReader(_server_ctx(pki)).start()
    out = open_out(f"tls://127.0.0.1:{rx.port}", CotTls(pki["client"], pki["client_key"], pki["other_ca"]))
    assert isinstance(out, StreamOut)
    task = asyncio.ensure_future(out.run())
    try:
        with caplog.at_level(logging.WARNING, "topgimbal.mavlink"):
            out.offer(_event(0))
            await eventually(lambda: "cannot connect" in caplog.text, timeout=20.0)
        assert "certificate verify failed" in caplog.text and rx.raw == [] and out.connects == 0
    finally:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        await rx.stop()


async def test_tls_checks_the_name_the_server_certificate_carries(
    pki: dict[str, str], caplog: pytest.LogCaptureFixture
) -> None:
    """The server's certificate names 127.0.0.1: asked to expect another name, the client refuses."""
    rx = await TakReader(_server_ctx(pki)).start()
    out = open_out(f"tls://127.0.0.1:{rx.port}", CotTls(pki["client"], pki["client_key"], pki["ca"], "tak.invalid"))
    task = asyncio.ensure_future(out.run())
    try:
        with caplog.at_level(logging.WARNING, "topgimbal.mavlink"):
            out.offer(_event(0))
            await eventually(lambda: "cannot connect" in caplog.text, timeout=20.0)
        assert "certificate verify failed" in caplog.text and "tak.invalid" in caplog.text and rx.raw == []
    finally:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        await rx.stop()


def test_tls_options_are_checked_before_anything_starts(pki: dict[str, str], tmp_path: Path) -> None:
    url = "tls://127.0.0.1:8089"
    with pytest.raises(CotConfigError, match="together"):
        open_out(url, CotTls(cert=pki["client"]))
    with pytest.raises(CotConfigError, match="cannot be used"):
        open_out(url, CotTls(pki["client"], pki["client_key"], str(tmp_path / "missing-ca.pem")))
    with pytest.raises(CotConfigError, match="cannot be used"):
        open_out(url, CotTls(pki["client"], pki["server_key"], pki["ca"]))  # a key that is not the certificate's
    with pytest.raises(CotConfigError, match="tls:// only"):
        open_out("tcp://127.0.0.1:8087", CotTls(ca=pki["ca"]))
    for bad in ("http://127.0.0.1:8087", "tcp://127.0.0.1", "tls://:8089", "127.0.0.1:8087", "tcp://127.0.0.1:99999"):
        with pytest.raises(CotConfigError, match="expected udp://HOST:PORT"):
            parse_url(bad)


async def test_the_bridge_streams_over_mutual_tls_from_the_command_line(rig_factory, pki: dict[str, str]) -> None:
    """`mavlink --cot tls://... --cot-cert --cot-key --cot-ca` as parsed by the CLI, the bridge's
    own sender, an autopilot's position: the vehicle where the autopilot says, over mutual TLS."""
    import math

    from pymavlink.dialects.v20 import common as ml

    from topgimbal.cli.main import build_parser
    from topgimbal.cli.mavlink_cmd import build_config

    rx = await TakReader(_server_ctx(pki)).start()
    argv = ["mavlink", "--url", "udp://127.0.0.1:5000", "--model", "SIP", "--mavlink", "udpin:127.0.0.1:0",
            "--cot", f"tls://127.0.0.1:{rx.port}", "--cot-cert", pki["client"], "--cot-key", pki["client_key"],
            "--cot-ca", pki["ca"]]  # fmt: skip
    parsed = build_config(build_parser().parse_args(argv))
    tls = parsed.cot_tls  # type: ignore[attr-defined]
    assert tls == CotTls(pki["client"], pki["client_key"], pki["ca"])
    rig = await rig_factory("SIP", cot=parsed.cot, cot_tls=tls)  # type: ignore[attr-defined]
    autopilot = type(rig.peer)(sysid=1, compid=1)
    await autopilot.connect(rig.bridge.addresses[0][1])

    async def feed() -> None:
        while True:
            autopilot.send(ml.MAVLink_attitude_message(0, 0.0, 0.0, math.radians(90.0), 0, 0, 0))
            autopilot.send(ml.MAVLink_global_position_int_message(
                0, round(LAT * 1e7), round(LON * 1e7), 650_000, 100_000, 0, 0, 0, 0))  # fmt: skip
            await asyncio.sleep(0.2)

    feeder = asyncio.ensure_future(feed())
    try:
        await eventually(lambda: any(m.cotEvent.type == "a-f-A-M-F-Q" for m in rx.events), timeout=20.0)
    finally:
        feeder.cancel()
        autopilot.close()
        await rx.stop()
    vehicle = next(m for m in rx.events if m.cotEvent.type == "a-f-A-M-F-Q").cotEvent
    assert (vehicle.uid, vehicle.lat, vehicle.lon) == ("topgimbal-SIP-1", LAT, LON)
    assert dict(x[0] for x in rx.peers[0]["subject"])["commonName"] == "tak-client"
