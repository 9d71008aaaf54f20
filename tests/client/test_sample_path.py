"""The per-sample path's shortcuts give what the general code gives: a message whose command
negates nothing under the client's signs passes as it is (the same object), one that does is
mapped as `map_message` maps it; the state cache's Stamped and GimbalAttitude objects, made
without their frozen __init__, equal the constructor's in every field and stay frozen."""

from __future__ import annotations

import dataclasses

import pytest

from topgimbal.client.signs import MessageSigns, map_message
from topgimbal.client.state import GimbalAttitude, Stamped, StateCache, attitude_of
from topgimbal.protocol import Message, get_model
from topgimbal.protocol.signs import negated_fields, resolve_signs

pytestmark = pytest.mark.virtual


def _sample(model: str, yaw: float, pitch: float, roll: float) -> Message:
    """A GAC answer as the device sends it, decoded."""
    dialect, _ = get_model(model)
    request = dialect.encode("GAC", read=True)
    return dialect.decode(dialect.response(request, yaw_deg=yaw, pitch_deg=pitch, roll_deg=roll))


@pytest.mark.parametrize("model", ["C12", "C20"])
def test_a_command_that_negates_nothing_passes_as_it_is(model: str) -> None:
    _, m = get_model(model)
    signs = resolve_signs(m, None)
    message = _sample(model, 12.5, -30.25, 1.0)
    mapper = MessageSigns(signs)
    assert negated_fields(message.spec, signs) == ()  # SkyDroid's wire is the API's convention
    assert mapper(message) is message
    assert map_message(message, signs).fields == message.fields  # what the general mapping gives


@pytest.mark.parametrize(
    ("model", "override"),
    [("SIP", None), ("C12", {"pitch": -1}), ("C12", {"yaw": -1, "roll": -1}), ("C12", {"attitude.pitch": -1})],
)
def test_a_command_that_negates_a_field_is_mapped_as_map_message_maps_it(
    model: str, override: dict[str, int] | None
) -> None:
    _, m = get_model(model)  # SIP: TOPOTEK's pitch is down-positive on the wire
    signs = resolve_signs(m, override)
    message = _sample(model, 12.5, -30.25, 1.0)
    mapper = MessageSigns(signs)
    got = mapper(message)
    assert got is not message and got == map_message(message, signs)
    negated = negated_fields(message.spec, signs)
    assert negated  # the override reaches GAC
    for name, value in message.fields.items():
        assert got.fields[name] == (-value + 0.0 if name in negated else value)
    assert mapper(message) == got  # the cached decision gives the same again


def test_the_state_cache_objects_equal_the_constructors() -> None:
    message = _sample("C12", 12.5, -30.25, 1.0)
    cache = StateCache()
    keyed = cache.apply(message, 7.0, 1764465000.25)
    for key, value in keyed.items():
        got = cache.values[key]
        assert got == Stamped(value, 7.0, 1764465000.25) and type(got) is Stamped
        with pytest.raises(dataclasses.FrozenInstanceError):
            got.t = 0.0  # type: ignore[misc]
    att = attitude_of(keyed, "attitude", "GAC", 7.0, 1764465000.25)
    assert att == GimbalAttitude(12.5, -30.25, 1.0, 7.0, 1764465000.25, "GAC")
    assert hash(att) == hash(GimbalAttitude(12.5, -30.25, 1.0, 7.0, 1764465000.25, "GAC"))
    assert att is not None and att.as_dict() == dataclasses.asdict(
        GimbalAttitude(12.5, -30.25, 1.0, 7.0, 1764465000.25)
    )
    with pytest.raises(dataclasses.FrozenInstanceError):
        att.yaw_deg = 0.0  # type: ignore[misc]


def test_the_per_frame_objects_have_no_dict_and_still_pickle_copy_and_compare() -> None:
    """A fleet server replaces a client's Stamped and GimbalAttitude objects, and writes its link
    monitor, engine, stream control, state cache and counters, on every sample of each of 1,000
    cameras: slots, not a __dict__ (one block each instead of two, fewer cache misses per sample).
    They behave as before."""
    import copy
    import pickle

    from topgimbal.client.engine import Engine
    from topgimbal.client.link import LinkMonitor
    from topgimbal.client.notifier import Notifier
    from topgimbal.client.stats import LinkStats
    from topgimbal.client.streams import StreamControl

    message = _sample("C12", 12.5, -30.25, 1.0)
    cache = StateCache()
    keyed = cache.apply(message, 7.0, 1764465000.25)
    att = attitude_of(keyed, "attitude", "GAC", 7.0, 1764465000.25)
    stamped = cache.values["attitude.yaw_deg"]
    per_frame = [att, stamped, LinkStats(), LinkMonitor(clock=lambda: 0.0), Notifier(), MessageSigns({}),
                 Engine(clock=lambda: 0.0), cache, StreamControl(None)]  # type: ignore[arg-type]  # fmt: skip
    for obj in per_frame:
        assert not hasattr(obj, "__dict__"), type(obj).__name__
    for obj in (att, stamped):
        assert pickle.loads(pickle.dumps(obj)) == obj
        assert copy.copy(obj) == obj
    assert dataclasses.replace(att, yaw_deg=1.0) == GimbalAttitude(1.0, -30.25, 1.0, 7.0, 1764465000.25, "GAC")
    stats = LinkStats()
    stats.frames_in, stats.rtt_ms_last = 3, 1.23456
    d = stats.as_dict()
    assert list(d) == list(LinkStats.describe())  # every counter, in the documented order
    assert d["frames_in"] == 3 and d["rtt_ms_last"] == 1.235  # rounded as before


@pytest.mark.parametrize(("model", "override"), [("C12", None), ("SIP", None), ("C12", {"yaw": -1})])
def test_the_attitude_step_stores_and_returns_what_the_general_path_does(
    model: str, override: dict[str, int] | None
) -> None:
    """`apply_attitude` (apply + attitude_of in one step, per sample) leaves the same entries in the
    state cache and returns the same GimbalAttitude as the general path, on the frames it takes."""
    _, m = get_model(model)
    mapper = MessageSigns(resolve_signs(m, override))
    for yaw, pitch, roll in ((12.5, -30.25, 1.0), (-179.99, 90.0, 0.0), (0.0, -0.01, -45.5)):
        message = mapper(_sample(model, yaw, pitch, roll))
        fast, general = StateCache(), StateCache()
        fast.values["zoom.optical_x"] = general.values["zoom.optical_x"] = Stamped(2.0, 1.0, 2.0)  # kept
        att = fast.apply_attitude(message, 7.0, 1764465000.25)
        keyed = general.apply(message, 7.0, 1764465000.25)
        assert att == attitude_of(keyed, "attitude", "GAC", 7.0, 1764465000.25)
        assert att is not None and type(att.yaw_deg) is float and att.source == "GAC"
        assert fast.values == general.values and list(fast.values) == list(general.values)
        assert fast == general  # nothing else in the cache changed (the attitude is the caller's to set)


def test_the_attitude_step_leaves_every_other_frame_to_the_general_path() -> None:
    dialect, _ = get_model("C12")
    cache = StateCache()
    sdc = dialect.decode(dialect.response(dialect.encode("SDC", read=True), remaining_mb=100, total_mb=200))
    gac = _sample("C12", 1.0, 2.0, 3.0)
    partial = Message._make((*gac[:3], {"yaw_deg": 1.0, "pitch_deg": 2.0}, *gac[4:]))  # a field missing
    as_ints = Message._make((*gac[:3], {"yaw_deg": 1, "pitch_deg": 2, "roll_deg": 3}, *gac[4:]))
    request = dialect.decode(dialect.encode("GAC", read=True))  # the query: no values
    for other in (sdc, partial, as_ints, request):
        assert cache.apply_attitude(other, 7.0, 1.0) is None
    assert cache.values == {} and cache.attitude is None
