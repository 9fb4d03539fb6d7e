"""A full disk as one line: what was being written, where, how much it needs and how much is free.

Every write a run makes goes through one of a few doors (`atomic.atomic_open`, the checkpoint
saver, the sequence store, the curve writer, the simulator's pre-flight check); each turns a full
disk (ENOSPC, or a quota's EDQUOT) into `DiskFull`, a `UserError`, after removing what it had
half-written. `cli.run` turns any full-disk error that still escapes (one from a library's own
writes) into the same kind of line.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
from pathlib import Path
from typing import Iterator

from fabricjax.errors import UserError

FULL_ERRNOS = (errno.ENOSPC, errno.EDQUOT)


class DiskFull(UserError, OSError):
    """No space left for a write: `path`, `what` was being written, `needed` bytes (at least),
    `free` bytes free there. A user error (`cli.run` prints its one line) and an `OSError` (ENOSPC)."""

    def __init__(self, path: str | os.PathLike, what: str, needed: int | None = None, free: int | None = None):
        self.path, self.what, self.needed = str(path), what, needed
        self.free = free_bytes(path) if free is None else free
        super().__init__(self.message())
        self.errno, self.strerror, self.filename = errno.ENOSPC, os.strerror(errno.ENOSPC), self.path

    def message(self) -> str:
        need = f" needs {'at least ' if self.needed is not None else ''}{size(self.needed)}," if self.needed else ""
        return (
            f"no space left on the disk for {self.what} ({self.path}):{need} {size(self.free)} free there; "
            "nothing half-written was kept: free space (or give --workdir on a larger disk) and run again"
        )

    def __str__(self) -> str:
        return self.message()

    def __reduce__(self):  # crosses process boundaries (a simulation or import worker's error)
        return (DiskFull, (self.path, self.what, self.needed, self.free))


def size(n: float | None) -> str:
    """A size in the unit that keeps it readable: GB from 1 GB, MB from 1 MB, else kB."""
    n = float(n or 0)
    if n >= 1e9:
        return f"{n / 1e9:.1f} GB"
    if n >= 1e6:
        return f"{n / 1e6:.0f} MB"
    return f"{n / 1e3:.0f} kB"


def free_bytes(path: str | os.PathLike) -> int:
    """Free bytes on the disk of `path` (its nearest existing folder)."""
    p = Path(path).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    try:
        return shutil.disk_usage(p).free
    except OSError:
        return 0


def is_full(error: BaseException | None) -> bool:
    """Whether `error`, or an error it was raised from or during, is a full disk."""
    seen = set()
    while error is not None and id(error) not in seen:
        seen.add(id(error))
        if isinstance(error, OSError) and error.errno in FULL_ERRNOS:
            return True
        error = error.__cause__ or error.__context__
    return False


def full_path(error: BaseException) -> str | None:
    """The file a full-disk `error` (or one in its chain) names, if any."""
    while error is not None:
        if isinstance(error, DiskFull):
            return error.path
        if isinstance(error, OSError) and error.errno in FULL_ERRNOS and error.filename:
            return str(error.filename)
        error = error.__cause__ or error.__context__
    return None


def require(path: str | os.PathLike, needed: int, what: str, margin: float = 1.05) -> None:
    """Raise `DiskFull` before writing `needed` bytes of `what` to `path` where they would not fit
    (with a `margin` for the file system's own blocks)."""
    free = free_bytes(path)
    if needed * margin > free:
        raise DiskFull(path, what, needed, free)


@contextlib.contextmanager
def writing(path: str | os.PathLike, what: str, needed: int | None = None) -> Iterator[None]:
    """Turn a full disk inside the block into `DiskFull` naming `path` and `what`; the caller
    removes what it half-wrote (this only names the error)."""
    try:
        yield
    except DiskFull:
        raise
    except BaseException as e:
        if not is_full(e):
            raise
        raise DiskFull(path, what, needed) from None
