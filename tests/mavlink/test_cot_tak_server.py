"""CoT stored by a real TAK server: OpenTAKServer's TCP streaming input, its `cot` table read back.

OpenTAKServer needs PostgreSQL with PostGIS, RabbitMQ and Python >= 3.12: about 6 minutes to install
on a fresh machine, too much for `make test`, which does not select this module (marker `service`).
`make test-tak` runs it against a server that is up (`scripts/opentakserver-loopback start` brings
one up on loopback and prints the variables); selected without them, it fails and names them:

    TOPGIMBAL_TAK_SERVER=tcp://127.0.0.1:8088          its TCP streaming input
    TOPGIMBAL_TAK_DB=postgresql://ots:...@127.0.0.1/ots  its database (read with psql)

and for its TLS input (8089, `eud_handler --ssl`), a client certificate its CA signed for one of
its users (start prints them too; OpenTAKServer's certificate names `opentakserver`, not 127.0.0.1):

    TOPGIMBAL_TAK_TLS_SERVER=tls://127.0.0.1:8089
    TOPGIMBAL_TAK_TLS=CERT.pem,KEY.pem,CA.pem,opentakserver

`test_cot_stream.py` checks the stream on every run of `make test` with pytak's framing and takproto
as the reader."""

from __future__ import annotations

import asyncio
import os
import shutil
import subprocess
import uuid
import xml.etree.ElementTree as ET

import pytest

from topgimbal.geo import Fix as GeoFix
from topgimbal.geo import geoid
from topgimbal.outputs.cot import CotSender, CotTls, Sighting

from .conftest import eventually

pytestmark = [pytest.mark.external, pytest.mark.service]

SERVER = os.environ.get("TOPGIMBAL_TAK_SERVER")
DB = os.environ.get("TOPGIMBAL_TAK_DB")
LAT, LON = -35.36, 149.16
SIGHTINGS = 30


def _rows(uid: str) -> list[tuple[str, str, str]]:
    out = subprocess.run(["psql", DB or "", "-AtF", "\t", "-c", f"SELECT uid, type, replace(xml, chr(10), ' ') FROM cot WHERE uid LIKE "
                          f"'{uid}%' ORDER BY id"], capture_output=True, text=True, timeout=30, check=True)  # fmt: skip
    return [tuple(line.split("\t", 2)) for line in out.stdout.splitlines() if line]  # type: ignore[misc]


TLS_SERVER = os.environ.get("TOPGIMBAL_TAK_TLS_SERVER")
TLS = CotTls(*os.environ["TOPGIMBAL_TAK_TLS"].split(",")) if os.environ.get("TOPGIMBAL_TAK_TLS") else None


@pytest.mark.parametrize("transport", ["tcp", "tls"])
async def test_opentakserver_stores_every_event_sent(transport: str) -> None:
    url, tls = (SERVER, None) if transport == "tcp" else (TLS_SERVER, TLS)
    if not (url and DB and shutil.which("psql") and (transport == "tcp" or tls)):
        names = (
            "TOPGIMBAL_TAK_SERVER" if transport == "tcp" else "TOPGIMBAL_TAK_TLS_SERVER, TOPGIMBAL_TAK_TLS"
        ) + ", TOPGIMBAL_TAK_DB"
        pytest.fail(f"no OpenTAKServer {transport} input to test: set {names} (and have psql on PATH); "
                    "scripts/opentakserver-loopback start brings one up on loopback and prints them")  # fmt: skip
    uid = f"topgimbal-ots-{uuid.uuid4().hex[:8]}"  # this run's rows only
    corners = [GeoFix(LAT + dy, LON + dx, 580.0, 300.0, "flat", 5.0, 0.0, -45.0)  # type: ignore[arg-type]
               for dy, dx in ((1e-3, -1e-3), (1e-3, 1e-3), (-1e-3, 1e-3), (-1e-3, -1e-3))]  # fmt: skip
    target = GeoFix(LAT, LON + 2e-3, 580.0, 250.0, "flat", 4.0, 90.0, -45.0)  # type: ignore[arg-type]
    n = [0]

    def sighting() -> Sighting | None:
        if n[0] >= SIGHTINGS:
            return None
        n[0] += 1
        return Sighting(LAT, LON, 700.0, 90.0, -45.0, 0.0, 60.0, 34.0, target, corners, "rtsp://127.0.0.1:8554/main")

    # OpenTAKServer keeps one EUD per callsign and stores events only of known EUDs: a new callsign each run
    sender = CotSender(url, sighting, uid=uid, callsign=f"OTS test {uid[-8:]}", rate_hz=5, tls=tls)
    task = asyncio.ensure_future(sender.run())
    try:
        await eventually(lambda: n[0] >= SIGHTINGS and sender.sent == 3 * SIGHTINGS, timeout=60.0, what="all sent")
        await eventually(lambda: len(_rows(uid)) >= sender.sent, timeout=60.0, what="every event stored")
    finally:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
    rows = _rows(uid)
    print(f"OpenTAKServer stored {len(rows)} of {sender.sent} events sent over {url}")
    assert len(rows) == sender.sent == 3 * SIGHTINGS
    assert {r[1] for r in rows} == {"a-f-A-M-F-Q", "b-m-p-s-p-i", "u-d-f"}
    vehicle = ET.fromstring(next(r[2] for r in rows if r[1] == "a-f-A-M-F-Q").encode())  # each stored as sent
    point = vehicle.find("point")
    assert point is not None
    n_m = geoid.default().undulation_m(LAT, LON)  # type: ignore[union-attr]
    assert float(point.get("hae", "nan")) == pytest.approx(700.0 + n_m, abs=0.01)  # stored as sent: above the ellipsoid
