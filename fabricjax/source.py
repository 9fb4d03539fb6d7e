"""The package's own source code, as one fingerprint: what produced a result or trained a model.

A config names what a run computes, not the code that computes it: a change in how training
rounds (the image rotation's, for one) moves results and leaves every config as it was. Results
(`studies.tools.reproduce`) and the studies' checkpoint folders (`studies.common.runner.checkpoint_dir`) are
keyed with this fingerprint, so that other code reruns instead of reusing what older code made.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path


@functools.cache
def fingerprint() -> str:
    """sha256 over the source of every module of the `fabricjax` package (path and content)."""
    h = hashlib.sha256()
    root = Path(__file__).parent
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()
