"""The device CLI against a simulator running in a background thread (main() is synchronous)."""

from __future__ import annotations

import json

import pytest

from topgimbal.cli.main import main
from topgimbal.sim import BackgroundSimulator

pytestmark = [pytest.mark.loopback, pytest.mark.integration]


@pytest.fixture(scope="module", params=["C12", "SIP"])
def bg(request):
    listen = {"udp": [("127.0.0.1", 0)], "tcp": [("127.0.0.1", 0)], "serial": ["pty"]}
    with BackgroundSimulator(request.param, seed=7, listen=listen) as sim:
        yield sim


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("kind", ["udp", "tcp", "serial"])
def test_stable_forms(bg, capsys, kind):
    url = dict(bg.endpoints)[kind]
    model = bg.sim.model
    code, out, _ = run(capsys, "--url", url, "--model", model, "point", "3", "-2", "--json")
    assert code == 0
    code, out, _ = run(capsys, "--url", url, "--model", model, "attitude", "--json")
    att = json.loads(out)
    assert code == 0 and {"yaw_deg", "pitch_deg", "roll_deg"} <= set(att)
    assert abs(att["yaw_deg"] - 3) <= 0.5 and abs(att["pitch_deg"] + 2) <= 0.5
    photos = bg.call(lambda s: s.camera.photos_taken)
    assert run(capsys, "--url", url, "--model", model, "photo")[0] == 0
    assert bg.call(lambda s: s.camera.photos_taken) == photos + 1
    code, out, _ = run(capsys, "--url", url, "--model", model, "record", "start", "--json")
    assert code == 0 and json.loads(out) == {"recording": True} and bg.call(lambda s: s.camera.recording)
    code, out, _ = run(capsys, "--url", url, "--model", model, "record", "status")
    assert code == 0 and "True" in out
    code, out, _ = run(capsys, "--url", url, "--model", model, "record", "stop", "--json")
    assert json.loads(out) == {"recording": False} and not bg.call(lambda s: s.camera.recording)


@pytest.mark.parametrize("kind", ["udp", "tcp", "serial"])
def test_every_command(bg, capsys, tmp_path, kind):
    url, model = dict(bg.endpoints)[kind], bg.sim.model
    base = ["--url", url, "--model", model]

    def ok(*argv: str) -> dict | list:
        code, out, err = run(capsys, *base, *argv, "--json")
        assert code == 0, err
        return json.loads(out.strip().splitlines()[-1])

    assert ok("info")["dialect"] == bg.sim.dialect.name
    lines = run(capsys, *base, "attitude", "--watch", "--count", "3", "--rate", "20", "--json")[1].splitlines()
    assert len(lines) == 3 and all("pitch_deg" in json.loads(x) for x in lines)
    assert ok("rate", "4", "0", "--duration", "0.2")["stopped"] is True
    assert ok("stop")["ok"] and ok("center")["ok"]
    assert ok("mode", "lock")["mode"] == "lock"
    assert ok("zoom", "in")["ok"] and ok("zoom", "stop")["ok"]
    assert ok("focus", "auto")["ok"]
    assert ok("sd")["present"] is True
    assert ok("thermal", "palette", "ironbow") == {"palette": "ironbow"}
    assert ok("thermal", "palette") == {"palette": "ironbow"}
    assert "ip" in ok("net", "show")
    gw = ok("net", "show")["gateway"]
    assert ok("net", "set", "--gateway", gw, "--yes")["ok"]
    code, _, err = run(capsys, *base, "net", "set", "--gateway", gw)  # stdin is not a tty: no silent change
    assert code == 1 and "confirmation" in err
    # TOPOTEK hosts are P on the network and U on a UART; SkyDroid hosts are always U
    frame = "#TPPD2rREC0039" if model == "SIP" and kind != "serial" else "#TPUD2rREC003E"
    assert ok("raw", frame)["fields"] == {"state": "stopped"}
    assert ok("command", "REC", "--read")["fields"] == {"state": "stopped"}
    if model == "SIP":  # no altitude sent: no distance, and it says what is missing
        code, _, err = run(capsys, *base, "range")
        assert code == 1 and "ALT" in err
    else:  # the C12 has no rangefinder: refused before sending, a usage error (issue 26, item 5)
        code, _, err = run(capsys, *base, "range")
        assert code == 2 and err.startswith("topgimbal: error:") and len(err.strip().splitlines()) == 1
    snap = ok("monitor", "--count", "2", "--fps", "20")
    assert snap["state"]["attitude"] is not None and snap["link"]["connected"] is True
    code, out, _ = run(capsys, *base, "monitor", "--count", "2", "--fps", "20")
    assert code == 0 and "yaw / pitch / roll" in out and "frames in / out" in out

    log = tmp_path / "traffic.jsonl"
    cap = tmp_path / "traffic.pcapng"
    res = ok("log", str(log), "--seconds", "0.3", "--stream", "20", "--pcap", str(cap))
    assert res["frames"] > 3 and log.exists()
    # The capture holds exactly the frames of the log, as Wireshark will see them (topgimbal.wire).
    from topgimbal.protocol import Frame
    from topgimbal.wire import WireFrame, frames_in_capture

    logged = [json.loads(line)["raw"] for line in log.read_text().splitlines()[1:]]
    captured = [
        w.item.to_bytes().decode("latin-1")
        for w in frames_in_capture(cap)
        if isinstance(w, WireFrame) and isinstance(w.item, Frame)
    ]
    assert res["pcap_frames"] == len(logged) and captured == logged
    rep = ok("replay", str(log), "--fast")
    assert rep["sent"] >= 2 and rep["replies"] >= 1


def test_errors_are_one_line_and_nonzero(bg, capsys):
    url, model = bg.url, bg.sim.model
    code, _, err = run(capsys, "--url", url, "--model", model, "point", "500", "0")
    assert code == 2 and err.count("\n") == 1 and "YAW=500" in err  # named as typed; refused before sending
    code, _, err = run(capsys, "--model", model, "photo")
    assert code != 0 and "--url" in err
    code, _, err = run(
        capsys, "--url", "udp://127.0.0.1:9", "--model", model, "attitude", "--timeout", "0.05", "--retries", "0"
    )
    assert code == 1 and "no reply" in err
    code, _, err = run(capsys, "--url", url, "photo")  # no --model: auto-detected
    assert code == 0
