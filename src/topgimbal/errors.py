"""The exception tree of topgimbal.

TopGimbalError
├── FrameError            a byte string is not a well-formed frame
│   ├── ChecksumError     the checksum does not match the bytes before it
│   └── LengthError       the length character disagrees with the data
├── CatalogError          a catalog lookup or a value failed
│   ├── UnknownCommandError   identifier not in the dialect's catalog
│   ├── UnsupportedError      the device model does not support the command
│   └── FieldValueError       a value is out of range / of the wrong kind (also ValueError)
├── TransportError        the byte pipe failed or is closed
│   └── LinkLostError     the device went silent (UDP) or the link closed; resumes by itself
├── DeviceError           the device answered with the error frame (ERE)
└── RequestTimeoutError   no matching reply in time (also builtin TimeoutError)
"""

from __future__ import annotations


class TopGimbalError(Exception):
    """Base of every error raised by topgimbal."""


class FrameError(TopGimbalError, ValueError):
    """A byte string is not a well-formed TOP frame."""


class ChecksumError(FrameError):
    def __init__(self, message: str, *, expected: str, found: str) -> None:
        super().__init__(message)
        self.expected = expected
        self.found = found


class LengthError(FrameError):
    pass


class CatalogError(TopGimbalError):
    pass


class UnknownCommandError(CatalogError, KeyError):
    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class UnsupportedError(CatalogError):
    pass


class FieldValueError(CatalogError, ValueError):
    """A field value is out of range or of the wrong kind; names field, value and what is allowed."""

    def __init__(self, field: str, value: object, allowed: str) -> None:
        super().__init__(f"{field}={value!r} is not allowed: expected {allowed}")
        self.field = field
        self.value = value
        self.allowed = allowed


class TransportError(TopGimbalError, ConnectionError):
    pass


class LinkLostError(TransportError):
    """Nothing came from the device for the link timeout (UDP), or the link closed (TCP, serial).
    Pending requests and streams end with it; the client resumes when frames come back."""


class DeviceError(TopGimbalError):
    """The device answered a request with its error frame (ERE)."""


class RequestTimeoutError(TopGimbalError, TimeoutError):
    pass
