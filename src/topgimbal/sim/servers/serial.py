"""Serial: a device path, or the master side of a fresh pty pair."""

from __future__ import annotations

import asyncio
import os
import termios
import tty

from .common import BAUD, Sink


def configure_tty(fd: int, baud: int = BAUD) -> None:
    """Raw 8N1 at `baud`: no echo, no line editing, no CR/LF translation."""
    tty.setraw(fd)
    attrs = termios.tcgetattr(fd)
    speed = getattr(termios, f"B{baud}", termios.B115200)
    attrs[4] = attrs[5] = speed
    attrs[2] = (
        (attrs[2] & ~(termios.PARENB | termios.CSTOPB | termios.CSIZE)) | termios.CS8 | termios.CREAD | termios.CLOCAL
    )
    termios.tcsetattr(fd, termios.TCSANOW, attrs)


class SerialPeer:
    """A serial line: a device path, or the master side of a pty pair whose slave a client opens."""

    def __init__(self, sink: Sink, device: str, baud: int = BAUD) -> None:
        self.sink = sink
        self.baud = baud
        self._slave_fd: int | None = None
        if device == "pty":
            self.fd, self._slave_fd = os.openpty()
            configure_tty(self.fd, baud)
            configure_tty(self._slave_fd, baud)
            self.path = os.ttyname(self._slave_fd)
        else:
            self.fd = os.open(device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
            configure_tty(self.fd, baud)
            self.path = device
        os.set_blocking(self.fd, False)
        self._loop: asyncio.AbstractEventLoop | None = None

    def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._loop.add_reader(self.fd, self._readable)

    def _readable(self) -> None:
        try:
            data = os.read(self.fd, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            return  # pty without a reader on the other side (EIO): wait for the next client
        if data:
            self.sink(self, data, False)

    def send(self, data: bytes) -> None:
        # A pty buffer fills if nobody reads the slave; drop what does not fit rather than block
        # the event loop (a UART would overrun the same way).
        try:
            os.write(self.fd, data)
        except (BlockingIOError, InterruptedError, OSError):
            pass

    @property
    def url(self) -> str:
        return f"serial://{self.path}?baud={self.baud}"

    def close(self) -> None:
        if self._loop is not None:
            self._loop.remove_reader(self.fd)
        for fd in (self.fd, self._slave_fd):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
