"""The exception tree of topgimbal.

TopGimbalError                kind
├── FrameError                "frame"            a byte string is not a well-formed frame
│   ├── ChecksumError         "checksum"         the checksum does not match the bytes before it
│   └── LengthError           "length"           the length character disagrees with the data
├── CatalogError              "catalog"          a catalog lookup or a value failed
│   ├── UnknownCommandError   "unknown_command"  identifier not in the dialect's catalog (also KeyError)
│   ├── UnsupportedError      "unsupported"      the device model does not support the command
│   └── FieldValueError       "value"            a value is out of range / of the wrong kind (also ValueError)
├── InputError                "input"            an address or option refused before anything was sent
├── TransportError            "transport"        the byte pipe failed or is closed (also ConnectionError)
│   ├── AddressError          "address"          a device URL that is not usable (also an InputError)
│   └── LinkLostError         "link_lost"        the device went silent (UDP) or the link closed; resumes by itself
├── DeviceError               "device"           the device answered with the error frame (ERE)
│   └── DecodeError           "decode"           the device answered, but the answer cannot be decoded
├── NoAnswerError             "no_answer"        no answer: the base of the two below (catch this one)
│   ├── RequestTimeoutError   "timeout"          no matching reply in time (also builtin TimeoutError)
│   └── LinkLostError         (above)            also a NoAnswerError: a silent address ends in either
└── ModelMismatchError        "model_mismatch"   the device identified itself as another model than given

Every error has `kind`, a short stable string for programs (logs, JSON, the console) that does not
change when a message is reworded, and `request`: the request frame the error concerns, when there
is one (None otherwise), so a caller can log or retry exactly what was sent.

`DecodeError` derives from `DeviceError` on purpose: code that already catches `DeviceError` ("the
device did not give me a usable answer") keeps working, and code that cares can tell a refusal (ERE)
from an answer it could not read.
"""

from __future__ import annotations


class TopGimbalError(Exception):
    """Base of every error raised by topgimbal."""

    kind: str = "error"
    request: object | None = None  # the request frame (a protocol Frame) this error concerns

    def __init__(self, *args: object, request: object | None = None) -> None:
        super().__init__(*args)
        if request is not None:
            self.request = request


class FrameError(TopGimbalError, ValueError):
    """A byte string is not a well-formed TOP frame."""

    kind = "frame"


class ChecksumError(FrameError):
    kind = "checksum"

    def __init__(self, message: str, *, expected: str, found: str, request: object | None = None) -> None:
        super().__init__(message, request=request)
        self.expected = expected
        self.found = found


class LengthError(FrameError):
    kind = "length"


class CatalogError(TopGimbalError):
    kind = "catalog"


class UnknownCommandError(CatalogError, KeyError):
    kind = "unknown_command"

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class UnsupportedError(CatalogError):
    kind = "unsupported"


class FieldValueError(CatalogError, ValueError):
    """A field value is out of range or of the wrong kind; names field, value and what is allowed."""

    kind = "value"

    def __init__(self, field: str, value: object, allowed: str, *, request: object | None = None) -> None:
        super().__init__(f"{field}={_show(value)} is not allowed: expected {allowed}", request=request)
        self.field = field
        self.value = value
        self.allowed = allowed


def _show(value: object) -> str:
    """repr() of a value, shortened: a 10**400 or a megabyte string must not flood a log line."""
    try:
        text = repr(value)
    except (ValueError, RecursionError):  # ints beyond Python's digit limit, self-nesting data
        text = f"<{type(value).__name__}>"
    return text if len(text) <= 80 else text[:60] + f"... ({len(text)} characters)"


class InputError(TopGimbalError):
    """What the user gave (a device URL, an endpoint, a missing option) is not usable: refused before
    anything was sent. The CLI exits 2 for it, as for a malformed command line."""

    kind = "input"


class TransportError(TopGimbalError, ConnectionError):
    kind = "transport"


class AddressError(TransportError, InputError):
    """A device URL that is not usable (no scheme, an unknown scheme, no host, a port out of range).
    Still a TransportError, as it was before it had a name."""

    kind = "address"


class NoAnswerError(TopGimbalError):
    """Nothing (usable) came back: a request timed out, or the link went silent or closed. Catch
    this for "the device did not answer"; which one a silent address ends in depends on timing
    (a request's timeout, or the link monitor's silence first)."""

    kind = "no_answer"


class LinkLostError(TransportError, NoAnswerError):
    """Nothing came from the device for the link timeout (UDP), or the link closed (TCP, serial).
    Pending requests and streams end with it; the client resumes when frames come back."""

    kind = "link_lost"


class DeviceError(TopGimbalError):
    """The device answered a request with its error frame (ERE)."""

    kind = "device"


class DecodeError(DeviceError):
    """The device answered, but the answer fits none of the command's forms. `answer` is the frame
    received (when there is one), `request` what was sent."""

    kind = "decode"

    def __init__(self, message: str, *, answer: object | None = None, request: object | None = None) -> None:
        super().__init__(message, request=request)
        self.answer = answer


class RequestTimeoutError(NoAnswerError, TimeoutError):
    kind = "timeout"


class ModelMismatchError(TopGimbalError):
    """The device identified itself as another model than the one given (`fits`: the models its
    answers fit). Raised before anything that moves or changes the camera is sent: with the wrong
    model, signs and commands would be wrong and a confirmation read through them a wrong answer."""

    kind = "model_mismatch"

    def __init__(self, message: str, *, fits: tuple[str, ...] = (), request: object | None = None) -> None:
        super().__init__(message, request=request)
        self.fits = fits
