"""Issue 28: an error raised for a request carries it (`TopGimbalError.request`, the frame sent), as
httpx's errors carry theirs: timeouts, refusals, unconfirmed acknowledgements, a lost link, a
closed client, and through the CLI's re-raise (in-memory fake device, no sockets)."""

from __future__ import annotations

import asyncio
import copy

import pytest

import topgimbal
from topgimbal.client.engine import Engine, with_request
from topgimbal.errors import DeviceError, LinkLostError, RequestTimeoutError, TopGimbalError, TransportError
from topgimbal.protocol import Frame, get_model

pytestmark = pytest.mark.virtual


async def test_a_timeout_carries_the_request(fake):
    url = fake.start_memory()
    fake.muted = True
    async with topgimbal.connect(url, model="C12", timeout_s=0.05, retries=0, check_model=False) as cam:
        frame = cam.build("GAC", read=True)
        with pytest.raises(RequestTimeoutError) as err:
            await cam.send_request(frame)
    assert err.value.request == frame


async def test_a_refusal_and_a_wrong_acknowledgement_carry_the_request(fake):
    url = fake.start_memory()
    d = fake.dialect

    def device(frame):
        if frame.ident == "GAY":  # echoes another angle than the one it was sent
            return [d.encode("GAY", yaw_deg=45.0).swapped().to_bytes()]
        if frame.ident == "GAC":  # refuses the attitude query with the error frame
            return [Frame("#TP", frame.dst, frame.src, "w", "ERE", b"!!").to_bytes()]
        return fake.default(frame)

    fake.handler = device
    async with topgimbal.connect(url, model="C12", timeout_s=0.3, check_model=False) as cam:
        sent = cam.build("GAY", yaw_deg=10)
        with pytest.raises(DeviceError) as err:
            await cam.send_request(sent)
        assert err.value.request == sent and "does not carry the data sent" in str(err.value)
    async with topgimbal.connect(url, model="C12", timeout_s=0.3, check_model=False) as cam:
        query = cam.build("GAC", read=True)
        with pytest.raises(DeviceError) as err:
            await cam.send_request(query)
        assert err.value.request == query and "refused" in str(err.value)


async def test_a_closed_client_fails_each_pending_request_with_its_own_frame(fake):
    url = fake.start_memory()
    fake.muted = True
    cam = await topgimbal.connect(url, model="C12", timeout_s=5.0, retries=0, check_model=False)
    frames = [cam.build("GAC", read=True), cam.build("VER", read=True) if "VER" in cam.dialect.commands else None]
    frames = [f for f in frames if f is not None]
    tasks = [asyncio.ensure_future(cam.send_request(f)) for f in frames]
    await asyncio.sleep(0.05)
    await cam.close()
    errors = [await asyncio.wait_for(asyncio.gather(t, return_exceptions=True), 5.0) for t in tasks]
    for frame, (error,) in zip(frames, errors, strict=True):
        assert isinstance(error, TransportError) and error.request == frame
    with pytest.raises(TransportError) as err:
        await cam.send_request(frames[0])  # refused up front: still says which request
    assert err.value.request == frames[0]


def test_one_lost_link_error_becomes_one_copy_per_request():
    dialect, model = get_model("C12")
    now = [0.0]
    engine = Engine(clock=lambda: now[0], late_window_s=2.0, dup_window_s=0.05, model=model, dialect=dialect)
    a = dialect.encode("GAC", read=True)
    b = dialect.encode("GAY", yaw_deg=5.0)
    txs = [engine.submit(a, timeout_s=1.0), engine.submit(b, timeout_s=1.0)]
    shared = LinkLostError("link lost")
    engine.fail_all(shared)
    assert [tx.error.request for tx in txs] == [a, b]  # type: ignore[union-attr]
    assert shared.request is None  # the caller's object is left as it was
    assert [tx.error.args for tx in txs] == [shared.args, shared.args]  # type: ignore[union-attr]


def test_with_request_keeps_every_attribute_and_leaves_other_exceptions_alone():
    from topgimbal.errors import DecodeError

    dialect, _ = get_model("C12")
    frame = dialect.encode("GAC", read=True)
    answer = dialect.encode("GAY", yaw_deg=1.0)
    err = with_request(DecodeError("cannot read", answer=answer), frame)
    assert isinstance(err, DecodeError) and err.request == frame and err.answer == answer
    other = ValueError("x")
    assert with_request(other, frame) is other


def test_the_cli_keeps_the_request_when_it_adds_a_hint():
    from topgimbal.cli.model_check import with_hint as _with_hint

    dialect, _ = get_model("C12")
    frame = dialect.encode("GAC", read=True)
    err = _with_hint(TopGimbalError("refused", request=frame), "the device is a SIP", "C12")
    assert err.request == frame and "the device is a SIP" in str(err)
    assert copy.copy(err).request == frame
