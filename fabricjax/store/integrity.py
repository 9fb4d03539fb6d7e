"""Is a dataset still what was recorded? `verify` re-hashes every archive against the sha256 its
index recorded, re-validates every field (`archive.read_archive`), and checks that the steps are
regular: a frame interval above `GAP_FACTOR` nominal periods (30 ms at 50 Hz) means frames were lost
or a step was late. Such a gap is legal in an archive (the recorder skips a missed slot rather than
bunching steps up, and importers keep gaps rather than fill them), so `read_archive` accepts it and
verify reports it. Every archive of the folder is checked whatever another one holds; a reader that
fails other than with `ArchiveError` on a file is verify's own failure, reported with the file and
counted apart from the dataset's problems. It never writes: not into the dataset folder, not the
index."""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import numpy as np

from fabricjax.store import archive, dataset_index, workspace

GAP_FACTOR = 1.5  # capture jitter stays well below half a period; a lost frame makes 2 periods


@dataclasses.dataclass(frozen=True)
class Problem:
    file: str
    field: str
    reason: str

    def __str__(self) -> str:
        return f"{self.file}: {self.field}: {self.reason}"


def frame_gaps(timestamps: np.ndarray, rate: float = archive.STEP_RATE) -> np.ndarray:
    """Indices of the steps that follow a gap above `GAP_FACTOR` periods."""
    return np.flatnonzero(np.diff(timestamps) > GAP_FACTOR / rate) + 1


def _index_entries(root: Path, workdir) -> tuple[Path, dict[str, dict] | None, list[Problem]]:
    ipath = workspace.index_file(root, workdir)
    if not ipath.exists():
        return ipath, None, []
    try:
        doc = json.loads(ipath.read_text())
        return ipath, {t["file"]: t for t in doc["trials"]}, []
    except OSError as e:
        return ipath, None, [Problem(str(ipath), "<file>", f"unreadable index: {e.strerror or e}")]
    except (ValueError, KeyError, TypeError) as e:  # ValueError: not JSON, or not UTF-8
        return ipath, None, [Problem(str(ipath), "trials", f"malformed index: {e}")]


def _check_file(p: Path, entry: dict | None, ipath: Path) -> list[Problem]:
    """The problems of one archive: its bytes against the index entry, its fields, its steps."""
    problems = []
    if entry is not None and entry.get("sha256"):
        size = p.stat().st_size
        if size != entry.get("size"):
            problems.append(
                Problem(
                    str(p), "<file>", f"{size} bytes, the index recorded {entry.get('size')} (truncated or rewritten)"
                )
            )
        elif dataset_index.sha256_file(p) != entry["sha256"]:
            problems.append(
                Problem(
                    str(p), "<file>", f"sha256 differs from the one {ipath} recorded (bytes changed since indexing)"
                )
            )
    try:
        trial = archive.read_archive(p)
    except archive.ArchiveError as e:
        return problems + [Problem(e.path, e.field, e.problem)]
    rate = archive.layout(trial.meta).step_rate
    for k in frame_gaps(trial.timestamps, rate):
        dt = trial.timestamps[k] - trial.timestamps[k - 1]
        problems.append(
            Problem(
                str(p),
                "timestamps",
                f"irregular: step {k} comes {dt * 1e3:.1f} ms after step {k - 1} "
                f"(more than {GAP_FACTOR} periods of {1e3 / rate:.0f} ms: frames lost or a step late)",
            )
        )
    return problems


def verify(folder: os.PathLike | str, workdir: os.PathLike | str | None = None) -> tuple[list[Problem], dict]:
    """Every problem of the dataset in `folder`, and counts (archives, hashed against the index, and
    `failures`: the files verify itself could not check, each a Problem naming the exception)."""
    root = Path(folder)
    if not root.is_dir():
        raise archive.ArchiveError(root, "<folder>", "dataset folder does not exist")
    ipath, indexed, problems = _index_entries(root, workdir)
    files = sorted(root.glob("*.npz"))
    if not files:
        raise archive.ArchiveError(root, "<folder>", "the folder holds no trial archives (*.npz)")
    hashed, failures = 0, []
    for p in files:
        entry = (indexed or {}).get(p.name)
        hashed += bool(entry is not None and entry.get("sha256"))
        try:
            problems += _check_file(p, entry, ipath)
        except OSError as e:  # the file cannot be read at all (permissions, I/O): the dataset's problem
            problems.append(Problem(str(p), "<file>", f"unreadable: {e.strerror or e}"))
        # verify's own failure on this file: named, and the other files still checked
        except Exception as e:  # noqa: BLE001
            failures.append(Problem(str(p), "<verify>", f"verify failed on this file: {type(e).__name__}: {e}"))
    on_disk = {p.name for p in files}
    for name in sorted(set(indexed or {}) - on_disk):
        problems.append(Problem(str(ipath), f"trials[{name}]", f"listed archive is missing from {root}"))
    return problems, {
        "archives": len(files),
        "hashed": hashed,
        "index": str(ipath) if indexed is not None else None,
        "failures": failures,
    }
