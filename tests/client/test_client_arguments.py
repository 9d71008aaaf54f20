"""Bad arguments leave no trace: every public method of the client, given a wrong type or value for
any argument, raises a TopGimbalError that is a ValueError or TypeError before anything is sent,
and the next call on the same key works (issue 15, point 4)."""

from __future__ import annotations

import inspect
import math
import typing

import pytest

import topgimbal
from topgimbal.client import AsyncClient, Gimbal
from topgimbal.client.methods import api_method
from topgimbal.errors import TopGimbalError

pytestmark = pytest.mark.virtual

# What each method needs to be callable at all (the argument under test replaces one of these).
REQUIRED: dict[str, tuple] = {
    "request": ("TAS",),
    "send_raw": ("#TPUD2rREC003E",),
    "point": (1.0, 1.0),
    "set_mode": ("follow",),
    "zoom": ("in",),
    "digital_zoom": (2,),
    "focus": ("auto",),
    "thermal": ("palette",),
}

API = sorted(n for n in dir(AsyncClient) if isinstance(inspect.getattr_static(AsyncClient, n), api_method))


def wrong_values(annotation) -> list:
    """Values of the wrong type or out of any range, for a parameter annotated `annotation`."""
    args = set(typing.get_args(annotation)) | {annotation}
    out: list = [object(), [1]]
    if float in args or int in args:
        out += ["ten", math.nan, math.inf, True]
    if str in args:
        out += [5, b"bytes"]
    if bool in args:
        out += ["yes", 2]
    return out


def cases():
    for name in API:
        fn = inspect.getattr_static(AsyncClient, name).fn
        hints = typing.get_type_hints(fn)
        params = list(inspect.signature(fn).parameters.values())[1:]
        for i, p in enumerate(params):
            if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
                continue
            for bad in wrong_values(hints.get(p.name)):
                yield name, i, p, bad


def test_every_public_method_is_covered():
    assert {"request", "send_raw", "point", "set_angles", "photo", "sd_card", "thermal", "set_network"} <= set(API)
    assert len(list(cases())) > 150


@pytest.mark.parametrize("timeout_s", ["x", -1, 0, math.nan, object()])
async def test_a_bad_timeout_does_not_poison_the_key(fake, timeout_s):
    url = fake.start_memory()
    fake.answers["TAS"] = {"interval_s": 10}
    async with topgimbal.connect(url, model="C12", timeout_s=0.5) as cam:
        with pytest.raises(TopGimbalError) as err:
            await cam.request("TAS", read=True, timeout_s=timeout_s)
        assert isinstance(err.value, ValueError) and "timeout_s" in str(err.value)
        assert fake.received == []
        m = await cam.request("TAS", read=True)  # the key is free
        assert m.fields == {"interval_s": 10}


async def test_every_method_rejects_every_wrong_argument_before_sending(fake):
    url = fake.start_memory()
    fake.answers.update(TAS={"interval_s": 10}, IMG={"palette": "ironbow"}, REC={"state": "stopped"})
    async with topgimbal.connect(url, model="C12", timeout_s=0.3) as cam:
        checked = 0
        for name, i, p, bad in cases():
            args = list(REQUIRED.get(name, ()))
            kwargs = {}
            if p.kind == p.KEYWORD_ONLY or i >= len(args):
                kwargs[p.name] = bad
            else:
                args[i] = bad
            before = len(fake.received)
            with pytest.raises(TopGimbalError) as err:
                await getattr(cam, name)(*args, **kwargs)
            assert isinstance(err.value, (ValueError, TypeError)), (name, p.name, bad, err.value)
            assert len(fake.received) == before, f"{name}({p.name}={bad!r}) sent something"
            checked += 1
        assert checked > 150
        for ident in ("TAS", "IMG", "REC"):
            assert (await cam.request(ident, read=True)).fields  # nothing left half-done on any key


async def test_unknown_commands_and_values_are_value_errors(fake):
    url = fake.start_memory()
    async with topgimbal.connect(url, model="C12", timeout_s=0.3) as cam:
        for call in (
            cam.request("XYZ"),
            cam.request("TAS", interval_s="ten"),
            cam.request("TAS", bogus=1),
            cam.thermal("nonsense"),
            cam.focus("sideways"),
            cam.send_raw("#TPUD2rREC00FF"),  # wrong checksum
            cam.set_network(ip="300.1.1.1"),
        ):
            with pytest.raises(TopGimbalError) as err:
                await call
            assert isinstance(err.value, ValueError), err.value
        assert fake.received == []


@pytest.mark.loopback
@pytest.mark.parametrize(
    "option", [{"timeout_s": 0}, {"timeout_s": "1"}, {"retries": -1}, {"retries": 1.5}, {"link_timeout_s": -3}]
)
def test_bad_connect_options_are_rejected(option):
    with pytest.raises(TopGimbalError) as err:
        topgimbal.connect("udp://127.0.0.1:9", model="C12", **option)
    assert isinstance(err.value, ValueError)


def test_the_blocking_facade_has_real_typed_methods():
    assert "__getattr__" not in vars(Gimbal)
    for name in API:
        assert inspect.getattr_static(Gimbal, name) is inspect.getattr_static(AsyncClient, name)
    hints = typing.get_type_hints(inspect.getattr_static(Gimbal, "point").fn)
    assert hints["return"] is topgimbal.client.Attitude
