"""A wrong `--model` is noticed: the check on connect compares what the device says it is (VER,
VSN, PA2, MOD, HWV) with the model profiles, warns (log, `cam.model_check`, callbacks, one CLI
stderr line) and names the model that fits; errors mention `--model`."""

from __future__ import annotations

import json

import pytest

import topgimbal
from topgimbal.cli.main import main
from topgimbal.client import identity
from topgimbal.client.identity import Report
from topgimbal.errors import DecodeError
from topgimbal.protocol import get_model
from topgimbal.sim import BackgroundSimulator

pytestmark = [pytest.mark.loopback, pytest.mark.integration]


@pytest.fixture(scope="module")
def sims():
    listen = {"udp": [("127.0.0.1", 0)]}
    with (
        BackgroundSimulator("SIP", seed=3, listen=listen) as sip,
        BackgroundSimulator("C12", seed=3, listen=listen) as c12,
    ):
        yield {"SIP": sip, "C12": c12}


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_model_c12_against_a_sip_is_refused_and_names_the_sip(sims, capsys):
    url = sims["SIP"].url
    assert run(capsys, "--url", url, "--model", "SIP", "point", "0", "-30", "--json")[0] == 0
    code, out, err = run(capsys, "--url", url, "--model", "C12", "attitude", "--json")
    # The wrong model would read the wrong sign (the SIP's wire pitch is down-positive): refused
    # before the command, in one line naming the model that fits (issue 35.2; was a warning).
    assert code == 2 and out == "" and len(err.splitlines()) == 1, (code, out, err)
    assert "SIP" in err and "--model SIP" in err
    code, out, err = run(capsys, "--url", url, "--model", "SIP", "attitude", "--json")
    assert code == 0 and json.loads(out)["pitch_deg"] == pytest.approx(-30.0, abs=0.6) and err == ""


def test_model_sip_against_a_c12_fails_in_one_line_that_names_the_c12(sims, capsys):
    code, _out, err = run(capsys, "--url", sims["C12"].url, "--model", "SIP", "attitude", "--json")
    # The C12 refuses the SIP's identity queries and answers the C12's: refused before the command.
    assert code == 2 and len(err.splitlines()) == 1 and "--model C12" in err, err


def test_info_shows_the_check(sims, capsys):
    code, out, err = run(capsys, "--url", sims["C12"].url, "--model", "C12", "info", "--json")
    info = json.loads(out)
    assert code == 0 and info["version"] == "010502" and info["model_check"] == "ok" and err == ""


async def test_the_api_reports_the_verdict_and_calls_back(sims):
    seen: list[identity.Verdict] = []
    async with topgimbal.connect(sims["SIP"].url, model="C12", timeout_s=0.5) as cam:
        cam.on_model_check(seen.append)
        verdict = await cam.wait_model_check(5.0)
        assert verdict.status == "mismatch" and verdict.fits == ("SIP",) and verdict.reported["model_name"] == "SIP"
        assert cam.model_check is verdict and seen and seen[-1].status == "mismatch"
        assert "SIP" in (await cam.identify())["model_check"]


async def test_the_check_can_be_turned_off(sims):
    async with topgimbal.connect(sims["C12"].url, model="C12", timeout_s=0.5, check_model=False) as cam:
        await cam.get_attitude()
        assert cam.model_check.status == "off" and cam.stats.frames_out == 1  # only the GAC


async def test_detect_model_finds_each_dialect(sims):
    for name, bg in sims.items():
        async with topgimbal.connect(bg.url, model="C12", timeout_s=0.5, check_model=False) as cam:
            assert await cam.detect_model() == name


async def test_an_answer_only_another_dialect_reads_names_the_model(fake):
    """A C12 client whose SD card query is answered the TOPOTEK way (one figure): the error says
    what it reads as and which --model fits."""
    sip_dialect, _ = get_model("SIP")
    url = fake.start_memory()

    def handler(frame):
        if frame.ident == "SDC":
            return [sip_dialect.response(frame, capacity_mb=1000).to_bytes()]
        return fake.default(frame)

    fake.handler = handler
    async with topgimbal.connect(url, model="C12", timeout_s=0.3, check_model=False) as cam:
        with pytest.raises(DecodeError) as err:
            await cam.sd_card()
    text = str(err.value)
    assert "topotek" in text and "--model SIP" in text and err.value.kind == "decode"


# -- the judging itself (pure) ----------------------------------------------------------------------


def test_judge_by_model_name_version_and_foreign_frames():
    c12 = get_model("C12")[1]
    ok = identity.judge(c12, [Report("version", "VER", "skydroid", "010502")])
    assert ok.status == "ok"
    named = identity.judge(c12, [Report("model_name", "MOD", "skydroid", "C13")])
    assert named.status == "mismatch" and named.fits == ("C13",) and "--model C13" in named.message
    by_version = identity.judge(c12, [Report("version", "VER", "skydroid", "V1.0.78")])
    assert by_version.fits == ("C11",)
    unknown = identity.judge(c12, [Report("version", "VER", "skydroid", "V9.9.9")])
    assert unknown.status == "unknown"  # firmware the profiles do not know is no evidence
    foreign = identity.judge(c12, [Report("version", "VSN", "topotek", None, foreign=True)])
    assert foreign.status == "mismatch" and foreign.fits == ("SIP",)
    # several models share a version: the one the client was told is among them
    c10pro = get_model("C10Pro")[1]
    assert identity.judge(c10pro, [Report("version", "VER", "skydroid", "V1.2.0")]).status == "ok"


def test_best_guess_prefers_the_model_name_and_the_default_among_equals():
    assert identity.best_guess([Report("model_name", "PA2", "topotek", "SIP")], "C12") == "SIP"
    shared = [Report("version", "VER", "skydroid", "V1.2.0")]
    assert identity.best_guess(shared, "C12") == "C10"  # C10 and C10Pro report it; C12 does not
    assert identity.best_guess([Report("version", "VER", "skydroid", "whatever")], "C12") == "C12"
    assert identity.best_guess([Report("version", "VER", "skydroid")], "C12") is None
