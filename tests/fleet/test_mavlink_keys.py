"""`topgimbal zenoh --mavlink-keys` as its own process with two simulated cameras, seen by an
independent Zenoh program (eclipse-zenoh only) in BlueOS mavlink-server's key shape: each camera's
HEARTBEAT, GIMBAL_DEVICE_ATTITUDE_STATUS and CAMERA_INFORMATION under its own component ids, a
COMMAND_LONG put on mavlink/in moving the second camera only and acknowledged on
mavlink/SYS/COMP/COMMAND_ACK, hostile input on mavlink/in dropped while the server goes on."""

from __future__ import annotations

import asyncio
import json
import sys
from typing import Any

import pytest

from .conftest import eventually, raw_session
from .test_zenoh_server import _serve, _stop

pytestmark = [pytest.mark.loopback, pytest.mark.integration]

HEADER_KEYS = ["system_id", "component_id", "sequence", "message_id"]


def _command(target_comp: int, command: str, params: list[float], seq: int = 1, confirmation: int = 0) -> str:
    msg: dict[str, Any] = {"type": "COMMAND_LONG", "target_system": 1, "target_component": target_comp,
                           "command": {"type": command}, "confirmation": confirmation}  # fmt: skip
    for i, p in enumerate(params, 1):
        msg[f"param{i}"] = p
    return json.dumps({"header": {"system_id": 255, "component_id": 190, "sequence": seq}, "message": msg})


async def _send_until(session: Any, make: Any, done: Any, what: str, attempts: int = 6, wait_s: float = 10.0) -> None:
    """Put a command on mavlink/in and, as a ground station does, send it again with the next
    `confirmation` while nothing answers: a Zenoh put is dropped under congestion (its default),
    as a UDP datagram may be lost."""
    for confirmation in range(attempts):
        await asyncio.to_thread(session.put, "mavlink/in", make(confirmation))
        end = asyncio.get_running_loop().time() + wait_s
        while asyncio.get_running_loop().time() < end:
            if done():
                return
            await asyncio.sleep(0.05)
    raise AssertionError(f"no answer after {attempts} attempts: {what}")


async def test_two_cameras_in_blueos_keys_commanded_through_mavlink_in(sims: Any, zport: int) -> None:
    cams = await sims(2)
    args = ["--listen", f"tcp/127.0.0.1:{zport}", "--mavlink-keys",
            "--camera", f"left={cams[0].url},C12", "--camera", f"right={cams[1].url},C12"]  # fmt: skip
    proc = await _serve(args)
    assert proc.stdout is not None
    ids_line = (await asyncio.wait_for(proc.stdout.readline(), 30)).decode()
    assert "left: gimbal 154, cameras 100,101; right: gimbal 171, cameras 102,103" in ids_line, ids_line
    session = await asyncio.to_thread(raw_session, zport)
    seen: dict[str, list[Any]] = {}

    def on_sample(sample: Any) -> None:
        if str(sample.key_expr) == "mavlink/in":
            return  # what this test itself puts there
        seen.setdefault(str(sample.key_expr), []).append(json.loads(sample.payload.to_string()))

    try:
        sub = session.declare_subscriber("mavlink/**", on_sample)
        wanted = [f"mavlink/1/{c}/{m}" for c in (154, 171) for m in ("HEARTBEAT", "GIMBAL_DEVICE_ATTITUDE_STATUS")]
        wanted += [f"mavlink/1/{c}/HEARTBEAT" for c in (100, 102)]
        await eventually(lambda: all(seen.get(k) for k in wanted) and bool(seen.get("mavlink/out")), 60,
                         "heartbeats and attitude of both cameras")  # fmt: skip

        hb = seen["mavlink/1/171/HEARTBEAT"][-1]
        assert list(hb) == ["header", "message"] and list(hb["header"]) == HEADER_KEYS
        assert hb["header"]["system_id"] == 1 and hb["header"]["component_id"] == 171
        assert hb["header"]["message_id"] == 0 and 0 <= hb["header"]["sequence"] <= 255
        assert hb["message"]["type"] == "HEARTBEAT"
        assert hb["message"]["mavtype"] == {"type": "MAV_TYPE_GIMBAL"}  # rust-mavlink's name for `type`
        assert hb["message"]["autopilot"] == {"type": "MAV_AUTOPILOT_INVALID"}
        assert isinstance(hb["message"]["base_mode"], str)  # a bit mask: bitflags' "A | B" text
        assert seen["mavlink/1/100/HEARTBEAT"][-1]["message"]["mavtype"] == {"type": "MAV_TYPE_CAMERA"}
        # each field alone, as mavlink-server publishes it
        assert seen["mavlink/1/171/HEARTBEAT/mavtype"][-1] == {"type": "MAV_TYPE_GIMBAL"}
        assert seen["mavlink/1/171/HEARTBEAT/type"][-1] == "HEARTBEAT"
        att = seen["mavlink/1/171/GIMBAL_DEVICE_ATTITUDE_STATUS"][-1]["message"]
        assert len(att["q"]) == 4 and att["gimbal_device_id"] in (0, 171)
        assert any(m["header"]["component_id"] == 154 for m in seen["mavlink/out"])

        # CAMERA_INFORMATION of both cameras, asked for as a ground station does
        for comp, seq in ((100, 2), (102, 3)):
            await _send_until(session, lambda n, comp=comp, seq=seq: _command(comp, "MAV_CMD_REQUEST_MESSAGE", [259], seq, n),
                              lambda comp=comp: bool(seen.get(f"mavlink/1/{comp}/CAMERA_INFORMATION")),
                              f"CAMERA_INFORMATION of {comp}")  # fmt: skip
        info = seen["mavlink/1/102/CAMERA_INFORMATION"][-1]["message"]
        assert isinstance(info["cam_definition_uri"], str) and isinstance(info["vendor_name"], list)
        assert len(info["vendor_name"]) == 32 and isinstance(info["flags"], str)
        assert "CAMERA_CAP_FLAGS_CAPTURE_IMAGE" in info["flags"].split(" | ")

        # hostile input on mavlink/in: dropped, the server goes on
        for bad in (b"not json", b"\xff\xfe", b"[1,2]", json.dumps({"header": {}, "message": {}}).encode(),
                    json.dumps({"header": {"system_id": 255, "component_id": 190},
                                "message": {"type": "NO_SUCH_MESSAGE"}}).encode(),
                    _command(171, "MAV_CMD_NO_SUCH", [0]).encode(),
                    _command(171, "MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW", ["x"]).encode(),  # type: ignore[list-item]
                    b"[" * 100_000, b"{" + b" " * 200_000 + b"}"):  # fmt: skip
            await asyncio.to_thread(session.put, "mavlink/in", bad)

        # point the second camera's gimbal manager (171): pitch, yaw in degrees, rates NaN (not given)
        seen.pop("mavlink/1/171/COMMAND_ACK", None)
        nan = float("nan")
        await _send_until(session, lambda n: _command(171, "MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW",
                                                      [-30.0, 25.0, nan, nan, 0, 0, 0], 4, n),
                          lambda: bool(seen.get("mavlink/1/171/COMMAND_ACK")), "COMMAND_ACK from component 171")  # fmt: skip
        ack = seen["mavlink/1/171/COMMAND_ACK"][-1]
        assert list(ack["header"]) == HEADER_KEYS and ack["header"]["message_id"] == 77
        assert ack["message"]["command"] == {"type": "MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW"}
        assert ack["message"]["result"] == {"type": "MAV_RESULT_ACCEPTED"}
        assert ack["message"]["target_system"] == 255 and ack["message"]["target_component"] == 190
        await eventually(lambda: abs(cams[1].gimbal.yaw_deg - 25.0) <= 1.0 and abs(cams[1].gimbal.pitch_deg + 30.0) <= 1.0,
                         60, "the second camera to reach yaw 25, pitch -30")  # fmt: skip
        assert cams[0].gimbal.yaw_deg == 0.0 and cams[0].gimbal.pitch_deg == 0.0
        assert "mavlink/1/154/COMMAND_ACK" not in seen
        sub.undeclare()
    finally:
        await asyncio.to_thread(session.close)
        code = await _stop(proc)
    assert proc.stderr is not None
    err = (await proc.stderr.read()).decode()
    assert code == 0, err
    assert "mavlink/in: dropped a message" in err and "Traceback" not in err, err


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--sysid", "0"], "--sysid 0: expected 1..255"),
        ([f"--camera=c{i}=udp://127.0.0.1:{5000 + i},C12" for i in range(2, 8)] + ["--no-thermal"],
         "7 cameras: one MAVLink system has 6 gimbal component ids"),
        ([f"--camera=c{i}=udp://127.0.0.1:{5000 + i},C12" for i in range(2, 5)],
         "4 cameras need 8 camera component ids"),
    ],
)  # fmt: skip
async def test_mavlink_keys_usage_errors_exit_2_before_opening_anything(extra: list[str], says: str) -> None:
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "topgimbal.cli.main", "zenoh", "--listen", "tcp/127.0.0.1:1", "--mavlink-keys",
        "--camera", "c1=udp://127.0.0.1:5001,C12", *extra,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    out, err = await asyncio.wait_for(proc.communicate(), 60)
    assert proc.returncode == 2 and b"serving" not in out
    assert f"topgimbal zenoh: error: --mavlink-keys: {says}" in err.decode()


def test_mavlink_keys_refuse_a_camera_that_is_another_model_at_start(
    capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    """As `mavlink --camera`: a SIP declared as a C12 beside a real C12 stops the server at start
    (exit 2, one line naming the camera, the model found and the form to give), before Zenoh is
    opened or anything is sent to a camera."""
    from topgimbal.cli.main import main
    from topgimbal.sim import BackgroundSimulator

    with (
        BackgroundSimulator("C12", seed=51, listen={"udp": [("127.0.0.1", 0)]}) as c12,
        BackgroundSimulator("SIP", seed=52, listen={"udp": [("127.0.0.1", 0)]}) as sip,
    ):
        code = main(["zenoh", "--listen", "tcp/127.0.0.1:1", "--mavlink-keys", "--camera", f"left={c12.url},C12",
                     "--camera", f"right={sip.url},C12", "--seconds", "1"])  # fmt: skip
        targets = sip.call(lambda s: (s.gimbal.axis("yaw").target, s.gimbal.axis("pitch").target))
    out, err = capsys.readouterr()
    assert code == 2 and "serving" not in out, (out, err)
    assert len(err.splitlines()) == 1 and err.startswith("topgimbal zenoh: error: --mavlink-keys: "), err
    assert f"camera right ({sip.url})" in err and "looks like a SIP, not a C12" in err, err
    assert "pass right=URL,SIP" in err and "auto" not in err and "left" not in err, err
    assert not [r for r in caplog.records if "looks like a SIP" in r.getMessage()]  # the error is the one line
    assert targets == pytest.approx((0.0, 0.0))


def test_mavlink_keys_status_says_where_each_cameras_feeds_come_from(capsys: pytest.CaptureFixture[str]) -> None:
    """`--status` as `mavlink --status`: per camera, each feed's source or why there is none (no
    autopilot on mavlink/in here), every period and once at the stop."""
    from topgimbal.cli.main import main
    from topgimbal.sim import BackgroundSimulator

    from .conftest import free_port

    with BackgroundSimulator("C12", seed=53, listen={"udp": [("127.0.0.1", 0)]}) as c12:
        code = main(["zenoh", "--listen", f"tcp/127.0.0.1:{free_port()}", "--mavlink-keys", "--camera",
                     f"left={c12.url},C12", "--seconds", "1", "--status", "0.5"])  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0, out
    blocks = out.split("feeds of left (C12):\n")[1:]
    assert blocks, out  # at least the one at the stop
    for feed in ("position", "attitude", "heading", "time"):
        assert f"  {feed:<9} none: " in blocks[-1] and "no autopilot heard on the MAVLink links" in blocks[-1], out


def test_status_without_mavlink_keys_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    from topgimbal.cli.main import main

    code = main(["zenoh", "--listen", "tcp/127.0.0.1:1", "--camera", "c1=udp://127.0.0.1:5001,C12", "--status", "1"])
    assert code == 2 and "--status needs --mavlink-keys" in capsys.readouterr().err
