"""`topgimbal.connect("zenoh/NAME?connect=...")`: a camera served by a FleetServer used like a local
one: same methods and results, the same exception classes, attitude streams, link changes,
and the per-camera bound on calls in progress."""

from __future__ import annotations

import asyncio
import json
import logging
from typing import Any

import pytest

import topgimbal
from topgimbal.client.remote import RemoteClient
from topgimbal.client.remote_keys import RemoteCallError, parse_zenoh_url
from topgimbal.errors import FieldValueError, LinkLostError, UnsupportedError
from topgimbal.fleet import CameraSpec, FleetServer
from topgimbal.fleet.specs import parse_camera, read_camera_file
from waiting import SETTLED_DEG, near

from .conftest import eventually, raw_call, raw_session

pytestmark = [pytest.mark.loopback, pytest.mark.integration]


async def test_remote_camera_is_used_like_a_local_one(sims: Any, zport: int) -> None:
    a, b = await sims(2)
    specs = [CameraSpec("a", a.url, "C12"), CameraSpec("b", b.url, "C12")]
    async with (
        FleetServer(specs, listen=[f"tcp/127.0.0.1:{zport}"], allow_remote=frozenset({"request"})),
        topgimbal.connect(f"zenoh/b?connect=tcp/127.0.0.1:{zport}") as cam,
        topgimbal.connect(b.url, model="C12") as local,
    ):
        assert isinstance(cam, RemoteClient) and cam.model.name == "C12" and cam.connected
        assert await cam.version() == await local.version()
        att = await cam.point(-15, 20)
        assert isinstance(att, topgimbal.client.Attitude) and abs(att.yaw_deg + 15) <= 0.5
        # the live axis settles on the target (point()'s tolerance applies to the reported attitude)
        await near("camera b's yaw", lambda: b.gimbal.yaw_deg, -15, margin=SETTLED_DEG, bound_s=30)
        assert a.gimbal.yaw_deg == 0.0
        sd = await cam.sd_card()
        assert sd.present and sd.total_mb and sd.total_mb > 0
        m = await cam.photo()
        assert m.ident == "CAP" and b.camera.photos_taken == 1 and a.camera.photos_taken == 0
        m = await cam.request("GAC", read=True)  # a read: callable without --allow-remote
        assert m.fields is not None and abs(m.fields["yaw_deg"] + 15) <= 0.5
        # the same exception classes as a local client
        with pytest.raises(FieldValueError):
            await cam.point(500, 0)  # checked on the server (the model's range)
        with pytest.raises(FieldValueError):
            await cam.point("far", 0)  # type: ignore[arg-type]  # checked here first
        with pytest.raises(FieldValueError):
            await cam.request("TAS", interval_s=30)  # 0..25 s on a C12
        with pytest.raises(UnsupportedError, match="rangefinder"):
            await cam.range()  # the C12 has no laser rangefinder
        assert await cam.palette() == "white_hot"
        samples = []
        async for s in cam.attitude(20):
            samples.append(s)
            if len(samples) == 5:
                break
        assert all(abs(s.yaw_deg + 15) <= 0.5 for s in samples)
        with pytest.raises(UnsupportedError):
            cam.subscribe(lambda m: None)


async def test_link_down_and_up_reach_a_remote_client(sims: Any, zport: int) -> None:
    (sim,) = await sims(1)
    spec = CameraSpec("cam", sim.url, "C12")
    async with FleetServer([spec], listen=[f"tcp/127.0.0.1:{zport}"], client_options={"link_timeout_s": 1.0}):
        cam = await topgimbal.connect(f"zenoh/cam?connect=tcp/127.0.0.1:{zport}")
        try:
            changes: list[tuple[bool, str]] = []
            cam.on_link_change(lambda up, reason: changes.append((up, reason)))
            raw = raw_session(zport)
            links: list[dict[str, Any]] = []
            states: list[dict[str, Any]] = []
            sub = raw.declare_subscriber(
                "topgimbal/cam/link", lambda s: links.append(json.loads(s.payload.to_string()))
            )
            sub2 = raw.declare_subscriber(
                "topgimbal/cam/state", lambda s: states.append(json.loads(s.payload.to_string()))
            )
            await asyncio.sleep(1.0)  # the attitude stream runs
            await sim.stop()  # the camera goes away
            await eventually(lambda: any(not x["up"] for x in links), 20, "a link-down message")
            await eventually(lambda: not cam.connected, 20, "the remote client sees the link down")
            down = next(x for x in links if not x["up"])
            assert down["reason"]
            with pytest.raises((LinkLostError, topgimbal.RequestTimeoutError)):
                await cam.version()
            await eventually(lambda: any(x["up"] is False and x["model"] == "C12" for x in states), 20, "state: down")
            assert "stats" in states[-1] and states[-1]["stats"]["link_losses"] >= 1
            sub.undeclare()
            sub2.undeclare()
            raw.close()
        finally:
            await cam.close()


async def test_calls_in_progress_are_bounded_per_camera(sims: Any, zport: int, caplog: Any) -> None:
    a, b = await sims(2)
    specs = [CameraSpec("a", a.url, "C12"), CameraSpec("b", b.url, "C12")]
    async with (
        FleetServer(specs, listen=[f"tcp/127.0.0.1:{zport}"], max_calls=1),
        topgimbal.connect(f"zenoh/a?connect=tcp/127.0.0.1:{zport}") as cam,
        topgimbal.connect(f"zenoh/b?connect=tcp/127.0.0.1:{zport}") as other,
    ):
        slow = asyncio.ensure_future(cam.point(80, 40))  # a long slew holds a's only call slot
        await eventually(lambda: a.gimbal.yaw_deg > 1.0, 20, "the slew started")
        with caplog.at_level(logging.WARNING, logger="topgimbal"):
            for _ in range(3):
                with pytest.raises(RemoteCallError) as busy:
                    await cam.version()
                assert busy.value.kind == "busy"
        lines = [r.getMessage() for r in caplog.records if "calls in progress" in r.getMessage()]
        assert len(lines) == 1 and "1 refused in all" in lines[0]  # three refusals, one line per 10 s
        assert isinstance(await other.version(), str)  # another camera is not affected
        att = await slow
        assert abs(att.yaw_deg - 80) <= 0.5


async def test_clients_on_a_session_the_caller_keeps(sims: Any, zport: int) -> None:
    """Two cameras on one session the caller opened (as the console does): each client reads its
    own camera's state, and closing them leaves the caller's session open and usable."""
    a, b = await sims(2)
    specs = [CameraSpec("a", a.url, "C12"), CameraSpec("b", b.url, "C12")]
    async with FleetServer(specs, listen=[f"tcp/127.0.0.1:{zport}"]):
        shared = raw_session(zport)
        try:
            url = f"zenoh/{{}}?connect=tcp/127.0.0.1:{zport}"
            ca = await RemoteClient(url.format("a"), session=shared).open()
            cb = await RemoteClient(url.format("b"), session=shared).open()
            assert ca.session is shared and cb.session is shared
            await cb.start_recording()
            await eventually(lambda: cb.served_state.get("recording") is True, 20, "b's state: recording")
            await eventually(lambda: ca.served_state.get("model") == "C12", 20, "a's state")
            assert ca.served_state.get("recording") is not True and b.camera.recording and not a.camera.recording
            await ca.close()
            assert ca.session is None
            assert isinstance(await cb.version(), str)  # the other client still works on it
            await cb.close()
            replies = raw_call(shared, "topgimbal/a/info", None, timeout=10)  # the session is still open
            assert replies and replies[0]["model"] == "C12"
        finally:
            shared.close()


async def test_nothing_served_under_that_name(zport: int) -> None:
    async with FleetServer([CameraSpec("a", "udp://127.0.0.1:9", "C12")], listen=[f"tcp/127.0.0.1:{zport}"]):
        with pytest.raises(LinkLostError, match="nothing answers"):
            await topgimbal.connect(f"zenoh/zz?connect=tcp/127.0.0.1:{zport}")


def test_url_and_camera_forms(tmp_path: Any) -> None:
    t = parse_zenoh_url("zenoh/cam-1?connect=tcp/127.0.0.1:7447&connect=tcp/127.0.0.1:7448")
    assert t.name == "cam-1" and t.connect == ("tcp/127.0.0.1:7447", "tcp/127.0.0.1:7448") and t.mode == "client"
    assert parse_zenoh_url("zenoh://cam?mode=peer&listen=tcp/127.0.0.1:7449").listen == ("tcp/127.0.0.1:7449",)
    for bad in ("zenoh/", "zenoh/a/b?connect=tcp/127.0.0.1:1", "zenoh/a", "zenoh/a?connect=x&bogus=1",
                "zenoh/a?mode=router&connect=tcp/127.0.0.1:1"):  # fmt: skip
        with pytest.raises(FieldValueError):
            parse_zenoh_url(bad)
    assert parse_camera("c1=udp://127.0.0.1:5000,c12") == CameraSpec("c1", "udp://127.0.0.1:5000", "c12")
    for bad in ("c1=udp://127.0.0.1:5000", "=udp://x:1,C12", "c1=zenoh/x,C12", "c 1=udp://x:1,C12", "c1=udp://x:1,ZZ"):
        with pytest.raises(FieldValueError):
            parse_camera(bad)
    f = tmp_path / "cams.txt"
    f.write_text("# fleet\nc1=udp://127.0.0.1:5000,C12\n\nc2=tcp://127.0.0.1:5001,C20\n")
    assert [s.name for s in read_camera_file(str(f))] == ["c1", "c2"]
    j = tmp_path / "cams.json"
    j.write_text(json.dumps([{"name": "x", "url": "udp://127.0.0.1:1", "model": "SIP"}]))
    assert read_camera_file(str(j))[0].model == "SIP"
    j.write_text('[{"name": 3}]')
    with pytest.raises(FieldValueError):
        read_camera_file(str(j))


def test_config_file_is_read_and_scouting_stays_off(tmp_path: Any) -> None:
    from topgimbal.client.zenoh_session import make_config

    f = tmp_path / "zenoh.json5"
    f.write_text(
        '{ mode: "peer", scouting: { multicast: { enabled: true } }, listen: { endpoints: ["tcp/127.0.0.1:7999"] } }'
    )
    conf = make_config(config_file=str(f))
    got = {k: json.loads(conf.get_json(k)) for k in ("scouting/multicast/enabled", "scouting/gossip/enabled")}
    assert got == {"scouting/multicast/enabled": False, "scouting/gossip/enabled": False}
    assert json.loads(conf.get_json("listen/endpoints")) == ["tcp/127.0.0.1:7999"]  # the file's: no --listen given
    conf = make_config(config_file=str(f), listen=["tcp/127.0.0.1:7998"])
    assert json.loads(conf.get_json("listen/endpoints")) == ["tcp/127.0.0.1:7998"]
    with pytest.raises(FieldValueError, match="configuration file"):
        make_config(config_file=str(tmp_path / "missing.json5"))
    with pytest.raises(FieldValueError):
        make_config(listen=["127.0.0.1:7447"])
    with pytest.raises(FieldValueError):
        make_config(mode="client")  # a client needs somewhere to connect


async def test_locate_over_zenoh_returns_the_local_fix_type_and_names_no_server_file(sims: Any, zport: int) -> None:
    """locate() remote returns the `geo.Fix` the local call returns, field for field; a terrain
    path (a file of the server's machine) is refused at both ends, before any file is opened."""
    from topgimbal.client.remote_keys import call_key
    from topgimbal.geo import Fix

    (a,) = await sims(1)
    where = {"position": (-35.36, 149.16, 650.0), "heading_deg": 30.0, "ground_alt_m": 600.0}
    async with (
        FleetServer([CameraSpec("a", a.url, "C12")], listen=[f"tcp/127.0.0.1:{zport}"]),
        topgimbal.connect(f"zenoh/a?connect=tcp/127.0.0.1:{zport}") as cam,
        topgimbal.connect(a.url, model="C12") as local,
    ):
        await local.point(10, -40)
        await near("camera a's pitch", lambda: a.gimbal.pitch_deg, -40, margin=SETTLED_DEG, bound_s=30)
        await near("camera a's yaw", lambda: a.gimbal.yaw_deg, 10, margin=SETTLED_DEG, bound_s=30)
        # standing still: two local fixes agree, and the remote one is the same fix (rounded as sent)
        before = await local.locate(**where)
        fix = await cam.locate(**where)
        mine = await local.locate(**where)
        assert isinstance(fix, Fix) and isinstance(mine, Fix) and isinstance(before, Fix)
        assert fix.source == mine.source == "flat"
        for f in (before, mine):
            assert abs(fix.lat_deg - f.lat_deg) < 1e-6 and abs(fix.lon_deg - f.lon_deg) < 1e-6, (fix, f)
            assert abs(fix.range_m - f.range_m) < 0.1 and abs(fix.elevation_deg - f.elevation_deg) < 0.01
        with pytest.raises(FieldValueError, match=r"terrain='/etc/hostname'.*server's machine"):
            await cam.locate(terrain="/etc/hostname", **where)
        # a peer that skips the client's check: refused by the server, no file opened
        with raw_session(zport) as peer:
            body = json.dumps({"terrain": "/etc/hostname", "ground_alt_m": 600.0})
            replies = await asyncio.to_thread(raw_call, peer, call_key("a", "locate"), body, 10)
        assert len(replies) == 1 and replies[0]["ok"] is False, replies
        assert "terrain is not taken from a remote caller" in json.dumps(replies[0])
