"""Atomic file writes: a reader sees the old file or the whole new one, never part of one.

Every file a person or a later run trusts (archives, indexes, cached features, results, figures)
is written through `atomic_open`: a hidden `.<name>.<random>.partial` in the same folder, flushed
and fsynced, then renamed over the target. A killed writer leaves only the `.partial`, which no
reader globs and the next dataset generation removes.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import IO, Iterator


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_open(path: os.PathLike | str, mode: str = "wb") -> Iterator[IO]:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
    try:
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes the file private; results and data are not
        with os.fdopen(fd, mode) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
