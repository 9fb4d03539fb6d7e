"""Atomic file writes: a reader sees the old file or the whole new one, never part of one.

Every file a person or a later run trusts (archives, indexes, cached features, results, figures)
is written through `atomic_open`: a hidden `.<name>.<random>.partial` in the same folder, flushed
and fsynced, then renamed over the target. A killed writer leaves only the `.partial`, which no
reader globs and the next dataset generation removes. A full disk is a `disk.DiskFull` naming the
file, what it is (`what`) and the bytes written when space ran out; the `.partial` is removed.

Files that belong together (a study's Markdown, JSON and figures) are written `together`: each
stays a `.partial` until the block ends, then all are renamed at once; a block that fails (a full
disk at the last figure) removes them all, leaving the older set whole.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import tempfile
from pathlib import Path
from typing import IO, Iterator

from fabricjax.store import disk


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_TOGETHER: contextvars.ContextVar[list[tuple[str, Path]] | None] = contextvars.ContextVar("together", default=None)


@contextlib.contextmanager
def together() -> Iterator[None]:
    """Every `atomic_open` inside the block takes effect when it ends, or (the block failed) none;
    a block inside another joins it."""
    if _TOGETHER.get() is not None:
        yield
        return
    pending: list[tuple[str, Path]] = []
    token = _TOGETHER.set(pending)
    try:
        yield
    except BaseException:
        for tmp, _ in pending:
            Path(tmp).unlink(missing_ok=True)
        raise
    finally:
        _TOGETHER.reset(token)
    for tmp, path in pending:
        os.replace(tmp, path)


@contextlib.contextmanager
def atomic_open(path: os.PathLike | str, mode: str = "wb", what: str = "a file") -> Iterator[IO]:
    path = Path(path)
    written = None
    try:
        with disk.writing(path, what):
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
    except disk.DiskFull as e:
        raise disk.DiskFull(path, what, None, e.free) from None
    try:
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes the file private; results and data are not
        with disk.writing(path, what):
            with os.fdopen(fd, mode) as f:
                try:
                    yield f
                    f.flush()
                    os.fsync(f.fileno())
                except BaseException:
                    written = _tell(f)
                    raise
            pending = _TOGETHER.get()
            if pending is None:
                os.replace(tmp, path)
            else:
                pending.append((tmp, path))
    except disk.DiskFull:
        Path(tmp).unlink(missing_ok=True)
        raise disk.DiskFull(path, what, written or None, disk.free_bytes(path)) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _tell(f: IO) -> int | None:
    try:
        return f.tell()
    except (OSError, ValueError):
        return None
