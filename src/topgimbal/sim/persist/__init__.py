"""Persistent settings on disk: checked on load, durable before acknowledged, atomic on write.

Writing: the JSON goes to a temporary file `.<name>.XXXXXXXX.tmp` in the same directory, is
flushed and fsynced, renamed over the old file (atomic on POSIX), and the directory is fsynced. A
kill -9 at any point leaves the old file or the new one, never a torn mix; a temporary left by a
crash is removed at the next start (`remove_stale_temps`).

Durability of acknowledgements (`GroupCommit`): the reply to a state-changing request is held until
a write that includes the change has reached the disk. Changes arriving while a write is in flight
share the next one (group commit), so a host writing at 100 Hz costs one fsync per batch, not one
per request.

Loading: a file that is not a regular file (FIFO, device, directory) is refused before it is
opened (and opened non-blocking, so a file swapped for a FIFO cannot hang the start); then its
size, nesting, JSON syntax, numbers (no NaN, Infinity, 1e400, 400-digit integers), and every key
and type against the device's own snapshot are checked, each failure as one line naming the file
and the key.
"""

from .load import FORMAT, MAX_BYTES, VERSION, StateFileError, load, validate
from .store import GroupCommit, dumps, remove_stale_temps, save, write_atomic

__all__ = [
    "FORMAT",
    "MAX_BYTES",
    "VERSION",
    "GroupCommit",
    "StateFileError",
    "dumps",
    "load",
    "remove_stale_temps",
    "save",
    "validate",
    "write_atomic",
]
