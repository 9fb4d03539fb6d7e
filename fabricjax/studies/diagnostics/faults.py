"""Faults injected into the code-keyed caches: the next run recomputes what is damaged or stale.

    python -m experiments.faults --results=results

Each case damages one load of the smoke preset's sequences (Minsound, proprioception and the
camera image, so PSDs, joints and frames are all cached) in a workspace of its own
(<workspace>/faults), while the features are cached (`input_source=memory`) or while the
sequences are written to memory-mapped files (`input_source=disk`):

  kill -9      the loading process and its feature workers are killed once the first files exist;
  full disk    the workspace's file system has too little room for what the load writes (a small
               tmpfs mounted for the case: it needs root, and says so where it cannot mount);
  truncated    a cache file of every feature (or every memory-mapped file) cut to half its size;
  other code   the cache written by another version of the code (its fingerprint and its arrays
               changed in that run), then read by this one.

A case holds when the damaged run ended killed, in one line, or with the clean result; nothing
half-written is left once the next run is done; and the next run gives exactly the clean run's
sequences (a digest of every array), having recomputed the damaged files.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from fabricjax import source
from fabricjax.config import Config
from fabricjax.reporting import results_files
from fabricjax.sequences import data
from fabricjax.sim import dataset as sim_dataset
from fabricjax.store import workspace
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents

STUDY = "faults"
PRESET = "smoke"
MODALITIES = ("internal", "proprio", "image")
STREAMS = ("audio", "proprio", "images")
INPUT_SOURCES = {"features": "memory", "sequences": "disk"}  # while what is written, how the load holds sequences
KILL_AFTER = 3  # files written before the kill
WAIT_S = 600  # the longest a load may take before the case fails


@dataclasses.dataclass(frozen=True)
class Case:
    """One injected fault and what followed it."""

    fault: str  # "kill -9", "full disk", "truncated", "other code"
    during: str  # "features" or "sequences"
    ended: str  # how the damaged run ended: "killed", its one line, or "the clean result"
    next_run: str  # what the next run gave
    left: list[str]  # half-written files left after the next run
    holds: bool


def _config(during: str) -> Config:
    return Config.from_preset(PRESET, modalities=MODALITIES, input_source=INPUT_SOURCES[during])


def load_once(folder: str, workdir: str, during: str, other_code: bool = False) -> None:
    """One load of the case's sequences, printing the digest of its arrays as the last line
    (`experiments.faults --load`). `other_code`: as another version of the code would load them,
    with another fingerprint and other arrays."""
    if other_code:
        from fabricjax.features import cache

        real_fingerprint, real_save, real_sequences = source.fingerprint, cache.save, data._sequences
        source.fingerprint = lambda roots, *a: "another version " + real_fingerprint(roots, *a)
        cache.save = lambda path, fingerprint, a: real_save(path, fingerprint, np.zeros_like(a))
        data._sequences = lambda *a: np.zeros_like(real_sequences(*a))
    sets = data.load_sequences(_config(during), folder, workdir=workdir, progress=False, workers=1 if other_code else 2)
    print(digest(sets))


def digest(sets: dict[str, data.SequenceSet]) -> str:
    h = hashlib.sha256()
    for split in sorted(sets):
        for m in sorted(sets[split].inputs):
            a = np.ascontiguousarray(sets[split].inputs[m])
            h.update(f"{split}/{m}/{a.dtype}/{a.shape}".encode())
            h.update(a.tobytes())
    return h.hexdigest()[:16]


def _command(folder: Path, workdir: Path, during: str, other_code: bool = False) -> list[str]:
    load = f"--load={folder},{workdir},{during}" + (",other_code" if other_code else "")
    return [sys.executable, "-m", "experiments.faults", load, f"--workdir={workdir}"]


def _load(folder: Path, workdir: Path, during: str, other_code: bool = False) -> tuple[int, str]:
    """(exit code, its digest, or the last line of its errors where it failed) of one load in a
    process of its own."""
    run = subprocess.run(_command(folder, workdir, during, other_code), capture_output=True, text=True, timeout=WAIT_S)
    lines = (run.stdout if run.returncode == 0 else run.stderr).strip().splitlines()
    return run.returncode, lines[-1] if lines else ""


def _written(workdir: Path, during: str) -> list[Path]:
    """What the load writes in the phase `during`: feature cache files, or memory-mapped sequences."""
    if during == "features":
        return sorted(workspace.features_dir(workdir).glob("*/*.npz"))
    return sorted(workspace.sequences_dir(workdir).glob("*/*.npy"))


def _half_written(workdir: Path) -> list[str]:
    return sorted(str(p.relative_to(workdir)) for p in workdir.rglob("*") if p.name.endswith(".partial"))


def _fresh(workdir: Path) -> None:
    for name in ("features", "sequences", "locks"):
        shutil.rmtree(workdir / name, ignore_errors=True)


def _next_run(folder: Path, workdir: Path, during: str, clean: str) -> tuple[str, bool]:
    code, line = _load(folder, workdir, during)
    if code != 0:
        return f"failed: {line}", False
    return ("the clean sequences" if line == clean else f"other sequences (digest {line})"), line == clean


def _case(fault: str, during: str, ended: str, ended_well: bool, folder: Path, workdir: Path, clean: str) -> Case:
    next_run, same = _next_run(folder, workdir, during, clean)
    left = _half_written(workdir)
    return Case(fault, during, ended, next_run, left, ended_well and same and not left)


def kill(folder: Path, workdir: Path, during: str, clean: str) -> Case:
    _fresh(workdir)
    proc = subprocess.Popen(
        _command(folder, workdir, during), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    deadline = time.monotonic() + WAIT_S
    while len(_written(workdir, during)) < KILL_AFTER and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    killed = proc.poll() is None
    if killed:
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    return _case("kill -9", during, "killed" if killed else "finished before the kill", killed, folder, workdir, clean)


def _can_mount(path: Path) -> bool:
    try:
        _tmpfs(path, 1 << 20)
    except (OSError, subprocess.CalledProcessError):
        return False
    subprocess.run(["umount", str(path)], check=False, capture_output=True)
    return True


def _tmpfs(path: Path, size: int) -> None:
    path.mkdir(parents=True, exist_ok=True)
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)], check=True, capture_output=True)


def full_disk(folder: Path, workdir: Path, during: str, clean: str) -> Case:
    """The load on a file system with room for half of what it writes (features: half the
    feature cache; sequences: the whole cache, and half the memory-mapped files)."""
    _fresh(workdir)
    code, _ = _load(folder, workdir, during)  # sizes what the load writes
    features = sum(p.stat().st_size for p in _written(workdir, "features"))
    room = (
        features // 2
        if during == "features"
        else features + sum(p.stat().st_size for p in _written(workdir, during)) // 2
    )
    mount = workdir.parent / f"{workdir.name}-small"
    if not _can_mount(mount):
        return Case("full disk", during, "not run: mounting a small file system needs root", "-", [], False)
    try:
        _tmpfs(mount, room + (1 << 20))  # the index and locks besides
        small = mount / "ws"
        code, line = _load(folder, small, during)
        one_line = code != 0 and line.startswith("error: ") and "Traceback" not in line
        ended = line if code != 0 else "the clean result"
        subprocess.run(["mount", "-o", f"remount,size={4 * room + (64 << 20)}", str(mount)], check=True)
        return _case("full disk", during, ended, one_line or line == clean, folder, small, clean)
    finally:
        subprocess.run(["umount", str(mount)], check=False, capture_output=True)


def truncate(folder: Path, workdir: Path, during: str, clean: str) -> Case:
    _fresh(workdir)
    _load(folder, workdir, during)
    files = _written(workdir, during)
    damaged = {}
    for d in sorted({p.parent for p in files}):  # one file in every folder: each feature, or the sequences
        p = next(f for f in files if f.parent == d)
        size = p.stat().st_size
        with open(p, "r+b") as f:
            f.truncate(size // 2)
        damaged[p] = size
    what = f"{len(damaged)} file{'s' if len(damaged) != 1 else ''} cut to half"
    case = _case("truncated", during, what, True, folder, workdir, clean)
    restored = all(p.exists() and p.stat().st_size == size for p, size in damaged.items())
    note = "" if restored else "; a damaged file was not written again"
    return dataclasses.replace(case, next_run=case.next_run + note, holds=case.holds and restored)


def other_code(folder: Path, workdir: Path, during: str, clean: str) -> Case:
    _fresh(workdir)
    code, line = _load(folder, workdir, during, other_code=True)
    ended = "the other version's sequences" if code == 0 and line != clean else f"unexpected: {line}"
    return _case("other code", during, ended, code == 0 and line != clean, folder, workdir, clean)


CASES: dict[str, Callable[[Path, Path, str, str], Case]] = {
    "kill -9": kill,
    "full disk": full_disk,
    "truncated": truncate,
    "other code": other_code,
}


def run(*, where: Location = Location()) -> dict[str, Any]:
    """Every case while the features are cached and while sequences are memory-mapped; writes
    results/faults.{md,json}."""
    root = workspace.root(where.workdir) / STUDY
    folder = sim_dataset.ensure_dataset(PRESET, root, streams=STREAMS)
    cases = []
    for during in INPUT_SOURCES:
        ws = root / f"ws-{during}"
        _fresh(ws)
        code, clean = _load(folder, ws, during)
        if code != 0:
            raise RuntimeError(f"the clean load failed: {clean}")
        for name, case in CASES.items():
            print(f"faults: {name} while {during} are written", flush=True)
            cases.append(case(folder, ws, during, clean))
    doc = {
        **documents.header(STUDY, module=__name__, command=where.command, preset=PRESET, modalities=list(MODALITIES)),
        "cases": [dataclasses.asdict(c) for c in cases],
        "holds": all(c.holds for c in cases),
    }
    return results_files.write(where.results_dir(), doc, markdown)


def markdown(doc: dict[str, Any]) -> str:
    cases = doc["cases"]
    lines = [
        "# Faults in the caches: the next run recomputes what is damaged",
        "",
        documents.header_markdown(doc),
        "",
        f"Each case damages one load of the {doc['preset']} preset's sequences "
        f"({', '.join(doc['modalities'])}) while the features are cached or while the sequences are written to "
        "memory-mapped files, then runs the load again; the next run must give exactly the clean run's "
        "sequences (a digest of every array). Half-written: files named `.partial` left after the next run. "
        "How each fault is injected: the module docstring of `fabricjax/studies/diagnostics/faults.py`.",
        "",
        results_files.markdown_table(
            ["Fault", "while writing", "the damaged run", "the next run", "half-written", "holds"],
            [
                [
                    c["fault"],
                    c["during"],
                    c["ended"],
                    c["next_run"],
                    ", ".join(c["left"]) or "none",
                    "yes" if c["holds"] else "**no**",
                ]
                for c in cases
            ],
        ),
        f"{sum(c['holds'] for c in cases)} of {len(cases)} cases hold.",
        "",
    ]
    return "\n".join(lines)


def parse_load(text: str) -> tuple[str, str, str, bool]:
    """--load's folder,workdir,during[,other_code]."""
    parts = text.split(",")
    return parts[0], parts[1], parts[2], parts[3:] == ["other_code"]
