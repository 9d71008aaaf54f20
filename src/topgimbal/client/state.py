"""What the client last heard from the device: typed values with the time they arrived.

Which frame tells what is catalog metadata: a field's `state_key` (`attitude.yaw_deg`, `version`,
`sd.remaining_mb`, `zoom.optical_x`, `range_m`...). Every keyed value lands in `StateCache.values`
under its key; the typed entries (`attitude`, `zoom`, `recording`, `sd`...) are derived from those
keys by their first part, so no table of identifiers is kept here."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field

from ..clock import monotonic, wall_time
from ..protocol import Message
from .acks import is_report
from .roles import sd_card_figures

JSON = dict[str, object]


@dataclass(frozen=True, slots=True)
class GimbalAttitude:
    """The gimbal's attitude as the camera reported it, in the API convention (degrees; yaw right-,
    pitch up-, roll right-positive). `t` is the monotonic arrival time, `wall` the wall-clock time.
    (By role: geo.Attitude is the vehicle's attitude, geo.Pointing the gimbal's angles in a view.)"""

    yaw_deg: float
    pitch_deg: float
    roll_deg: float
    t: float = 0.0
    wall: float = 0.0
    source: str = "GAC"

    def as_dict(self) -> JSON:
        return asdict(self)


Attitude = GimbalAttitude  # its name before issue 44 (topgimbal.client.Attitude): the same class


@dataclass(frozen=True)
class SdCard:
    present: bool
    remaining_mb: int | None
    total_mb: int | None

    def as_dict(self) -> JSON:
        return asdict(self)


@dataclass(frozen=True, slots=True)
class Stamped:
    """A value and when it arrived (monotonic `t`, wall-clock `wall`)."""

    value: object
    t: float
    wall: float

    def as_dict(self) -> JSON:
        v = self.value
        as_dict = getattr(v, "as_dict", None)
        return {"value": as_dict() if callable(as_dict) else v, "t": self.t, "wall": self.wall}


TYPED = ("zoom", "recording", "sd", "range_m", "version", "model_name", "temperature", "mode")


@dataclass(slots=True)  # one per client, written per sample: no __dict__ (fleet servers, issue 45)
class StateCache:
    """Last known device state. Each entry is None until the device has said something about it."""

    attitude: GimbalAttitude | None = None
    earth_attitude: GimbalAttitude | None = None  # the gyro's earth-frame reading (TOPOTEK GIC / GIA)
    zoom: Stamped | None = None  # optical magnification (x) or digital zoom
    recording: Stamped | None = None  # bool
    sd: Stamped | None = None  # SdCard
    range_m: Stamped | None = None  # float, or None value when the rangefinder failed
    version: Stamped | None = None
    model_name: Stamped | None = None
    temperature: Stamped | None = None
    mode: Stamped | None = None  # "follow" / "lock" as last commanded
    extra: dict[str, Stamped] = field(default_factory=dict)
    values: dict[str, Stamped] = field(default_factory=dict)  # every catalog state key heard

    def set(self, name: str, value: object) -> None:
        stamped = Stamped(value, monotonic(), wall_time())
        if name in TYPED:
            setattr(self, name, stamped)
        else:
            self.extra[name] = stamped

    def get(self, key: str) -> object:
        """The last value under a catalog state key (`"network.ip"`), or None."""
        s = self.values.get(key)
        return None if s is None else s.value

    def apply(self, message: Message, now: float | None = None, wall: float | None = None) -> dict[str, object]:
        """Take what a decoded frame (API convention) tells; returns {state key: value} it set.
        `now` / `wall`: the caller's clock reads (monotonic, UTC), one pair per datagram."""
        keyed = state_values(message)
        if not keyed:
            return keyed
        if now is None:
            now = monotonic()
        if wall is None:
            wall = wall_time()
        values = self.values
        for key, value in keyed.items():
            values[key] = _stamped(value, now, wall)
        if _may_type(keyed):
            for name, value in _typed(keyed, message).items():
                setattr(self, name, Stamped(value, now, wall))
        return keyed

    def apply_attitude(self, message: Message, now: float, wall: float) -> GimbalAttitude | None:
        """`apply` and `attitude_of(..., "attitude", ...)` in one step for a frame whose form keys
        exactly the three attitude axes and nothing else (every attitude sample): the same
        entries stored, the same GimbalAttitude returned (tests/client/test_sample_path.py). None
        for any other frame, or one whose three values are not all floats (what the decoder makes
        of them): the general path takes it.
        Per sample on a fleet server: no dict of keyed values, no per-key loop, no list."""
        form = message.form
        plan = _ATTITUDE_PLANS.get(id(form))
        if plan is None or plan[0] is not form:
            plan = _attitude_plan(form)
        names = plan[1]
        fields = message.fields
        if names is None or fields is None or message.is_error:
            return None
        y, p, r = fields.get(names[0]), fields.get(names[1]), fields.get(names[2])
        if not (type(y) is float and type(p) is float and type(r) is float):
            return None  # (ints, None, a missing field: as the general path does)
        values = self.values
        values[_KEY_YAW] = _stamped(y, now, wall)
        values[_KEY_PITCH] = _stamped(p, now, wall)
        values[_KEY_ROLL] = _stamped(r, now, wall)
        att = _new(GimbalAttitude)
        _A_YAW(att, y)
        _A_PITCH(att, p)
        _A_ROLL(att, r)
        _A_T(att, now)
        _A_WALL(att, wall)
        _A_SOURCE(att, message.frame.ident)
        return att

    @staticmethod
    def values_of(message: Message) -> dict[str, object]:
        """{state key: value} a decoded frame tells (nothing is stored)."""
        return state_values(message)

    def as_dict(self) -> JSON:
        out: JSON = {
            "attitude": self.attitude.as_dict() if self.attitude else None,
            "earth_attitude": self.earth_attitude.as_dict() if self.earth_attitude else None,
        }
        for name in TYPED:
            s: Stamped | None = getattr(self, name)
            out[name] = None if s is None else s.as_dict()
        out["extra"] = {k: s.as_dict() for k, s in self.extra.items()}
        out["values"] = {k: s.as_dict() for k, s in self.values.items()}
        return out


# Frozen dataclasses set each field through object.__setattr__ in __init__: three Stamped and one
# GimbalAttitude per attitude sample cost a third of what the state cache did per sample. Made here
# by setting each slot through its descriptor (what __init__ ends with), the same objects at half
# the cost; tests/client/test_sample_path.py compares them with the constructor's. Slots, not a
# __dict__: a fleet server replaces these four objects per sample for each of 1,000 cameras, and
# its per-sample cost is mostly memory (cache misses), so one block per object, not two, matters.
_new = object.__new__
_S_VALUE, _S_T, _S_WALL = (Stamped.__dict__[n].__set__ for n in ("value", "t", "wall"))
_A_YAW, _A_PITCH, _A_ROLL, _A_T, _A_WALL, _A_SOURCE = (
    GimbalAttitude.__dict__[n].__set__ for n in ("yaw_deg", "pitch_deg", "roll_deg", "t", "wall", "source")
)


def _stamped(value: object, t: float, wall: float) -> Stamped:
    s = _new(Stamped)
    _S_VALUE(s, value)
    _S_T(s, t)
    _S_WALL(s, wall)
    return s


def state_values(message: Message) -> dict[str, object]:
    """{state key: value} that a decoded frame tells: its form's keyed fields; for a device report
    (REC feedback...), the command's keys by field name."""
    fields, form, spec = message.fields, message.form, message.spec
    if fields is None or form is None or spec is None or message.is_error:
        return {}
    pairs: Iterable[tuple[str, str]] = form.keyed_fields
    if not pairs and is_report(message):
        pairs = spec.state_keys.items()
    return {key: fields[name] for name, key in pairs if name in fields}


_AXES = ("yaw_deg", "pitch_deg", "roll_deg")
_AXIS_KEYS: dict[str, tuple[str, ...]] = {}  # prefix -> its three keys (per frame on the hot path)
_KEY_YAW, _KEY_PITCH, _KEY_ROLL = (f"attitude.{a}" for a in _AXES)
# id(form) -> (form, its field names for yaw, pitch, roll when it keys those and nothing else, else
# None). The form is kept with its id (an id is reused only once its object is gone); bounded.
_ATTITUDE_PLANS: dict[int, tuple[object, tuple[str, str, str] | None]] = {}


def _attitude_plan(form: object) -> tuple[object, tuple[str, str, str] | None]:
    keyed = dict(getattr(form, "keyed_fields", ()) or ())  # field name -> state key
    by_key = {key: name for name, key in keyed.items()}
    names = None
    if len(keyed) == 3 and set(by_key) == {_KEY_YAW, _KEY_PITCH, _KEY_ROLL}:
        names = (by_key[_KEY_YAW], by_key[_KEY_PITCH], by_key[_KEY_ROLL])
    plan = (form, names)
    if len(_ATTITUDE_PLANS) >= 4096:
        _ATTITUDE_PLANS.clear()
    _ATTITUDE_PLANS[id(form)] = plan
    return plan


def attitude_of(
    keyed: Mapping[str, object], prefix: str, source: str, now: float | None = None, wall: float | None = None
) -> GimbalAttitude | None:
    """An Attitude from `<prefix>.yaw_deg` / `pitch_deg` / `roll_deg` values, when all are there
    (stamped `now` / `wall` when the caller has read the clocks)."""
    keys = _AXIS_KEYS.get(prefix)
    if keys is None:
        keys = _AXIS_KEYS[prefix] = tuple(f"{prefix}.{a}" for a in _AXES)
    nums = [float(v) for v in map(keyed.get, keys) if isinstance(v, (int, float))]
    if len(nums) != 3:
        return None
    att = _new(GimbalAttitude)
    _A_YAW(att, nums[0])
    _A_PITCH(att, nums[1])
    _A_ROLL(att, nums[2])
    _A_T(att, monotonic() if now is None else now)
    _A_WALL(att, wall_time() if wall is None else wall)
    _A_SOURCE(att, source)
    return att


_RECORDING = {"recording": True, "started": True, "start": True, "stopped": False, "stop": False}
# The heads of keys `_typed` reads: a frame with none of them (every attitude sample) skips it.
_TYPED_HEADS = frozenset({"recording", "zoom", "range_m", "version", "model_name", "temperature", "sd"})
_MAY_TYPE: dict[tuple[str, ...], bool] = {}  # bounded: one entry per key list (catalog forms repeat)


def _may_type(keyed: Mapping[str, object]) -> bool:
    """Whether `_typed` could find anything in `keyed` (cached per key list: forms repeat)."""
    names = tuple(keyed)
    hit = _MAY_TYPE.get(names)
    if hit is None:
        hit = any(k.split(".", 1)[0] in _TYPED_HEADS for k in names)
        if len(_MAY_TYPE) < 4096:
            _MAY_TYPE[names] = hit
    return hit


def _typed(keyed: Mapping[str, object], message: Message) -> dict[str, object]:
    """The typed entries a frame's keyed values update (attitudes are taken by the client core)."""
    out: dict[str, object] = {}
    for key, value in keyed.items():
        head = key.split(".", 1)[0]
        if head == "recording" and isinstance(value, str) and value in _RECORDING:
            out["recording"] = _RECORDING[value]
        elif head == "zoom" and key != "zoom.position" and "thermal" not in key:
            out["zoom"] = value
        elif head in ("range_m", "version", "model_name"):
            out[head] = value
        elif head == "temperature":
            out["temperature"] = message.fields
    if "sd.total_mb" in keyed:
        out["sd"] = SdCard(*sd_card_figures([{k.split(".", 1)[1]: v for k, v in keyed.items()}]))
    return out
