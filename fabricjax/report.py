"""Writing results people read: atomic JSON / Markdown files and the machine they were measured on."""

from __future__ import annotations

import json
import os
import platform
import subprocess
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from fabricjax import runtime
from fabricjax.atomic import atomic_open


# CPU features XLA:CPU compiles for: hosts that differ in them may round (and run) the same
# program differently, so every results file records which the host has.
VECTOR_UNITS = {"sse4_2", "avx", "avx2", "fma", "avx512f", "avx512bw", "avx512_bf16", "amx_tile"}


def machine() -> dict[str, Any]:
    """What a number was measured on; every results file carries this."""
    import jax

    cpu = platform.processor() or platform.machine()
    vector_units: list[str] = []
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name") and cpu == (platform.processor() or platform.machine()):
                cpu = line.split(":", 1)[1].strip()
            elif line.startswith("flags") and not vector_units:
                vector_units = sorted(set(line.split(":", 1)[1].split()) & VECTOR_UNITS)
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "vector_units": vector_units,
        "platform": platform.platform(),
        "python": platform.python_version(),
        "jax": jax.__version__,
        "jax_backend": jax.default_backend(),
        "devices": [str(d) for d in jax.devices()],
        # settings that change speed without changing code; recorded so a timing can be rerun alike
        "env": {k: os.environ[k] for k in ("XLA_FLAGS", "JAX_NUM_CPU_DEVICES", "GLIBC_TUNABLES", "OMP_NUM_THREADS") if k in os.environ},
    }


def git_commit() -> str:
    """'commit <hash>' of the source tree this package runs from (' + uncommitted changes' when
    git sees any), or 'no git checkout'."""
    root = Path(__file__).resolve().parents[1]
    try:
        run = lambda *a: subprocess.run(["git", "-C", str(root), *a], capture_output=True, text=True, timeout=10, check=True).stdout.strip()  # noqa: E731
        head, dirty = run("rev-parse", "--short=12", "HEAD"), run("status", "--porcelain", "--untracked-files=no", "--", "fabricjax", "experiments")
    except (OSError, subprocess.SubprocessError):
        return "no git checkout"
    return f"commit {head}" + (" + uncommitted changes" if dirty else "")


def _default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (set, tuple)):
        return list(o)
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON-serialisable: {type(o).__name__}")


def write_text(path: os.PathLike | str, text: str) -> Path:
    """Atomic: a reader sees the old file or the new one, never half of one. In a multi-process
    run every process computes the same document and only process 0 writes it (`runtime.is_primary`)."""
    if runtime.is_primary():
        with atomic_open(path, "w") as f:
            f.write(text)
    return Path(path)


def write_json(path: os.PathLike | str, doc: Any) -> Path:
    return write_text(path, json.dumps(doc, indent=1, default=_default) + "\n")


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    def cell(x):
        return str(x).replace("|", "\\|")

    lines = ["| " + " | ".join(map(cell, header)) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(map(cell, r)) + " |" for r in rows]
    return "\n".join(lines) + "\n"
