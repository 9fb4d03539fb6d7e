"""Results files: what every command that writes one records and how it writes it, below the
studies and the benchmarks alike (`studies.machinery.documents` builds a study's header on this one;
`bench.suite` writes its results with it).

`header` is the first fields of every results JSON: what ran, from which code (`git_commit`) and
with which `fingerprints` of what decides its numbers, when (`utc_now`) and on which `machine`;
`write` writes a document as results/<study>.json and its Markdown as .md atomically, saying what
it replaces (`replacing`); tables are `markdown_table`. The document holds the numbers a study
reports (per-seed accuracies, confusion counts, curves, times, fingerprints: kilobytes, tracked
beside its Markdown); what it says of every evaluated sequence (per-sample predictions and where
each sequence comes from: megabytes) goes to results/<study>`SAMPLES`, which is not tracked.
"""

from __future__ import annotations

import datetime
import hashlib
import json
import os
import platform
import subprocess
import sys
from pathlib import Path
from typing import Any, Callable, NamedTuple, Sequence

import numpy as np

from fabricjax import runtime, source
from fabricjax.sim import estimates
from fabricjax.store import atomic, provenance, workspace
from fabricjax.store.atomic import atomic_open

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
        "env": {
            k: os.environ[k]
            for k in ("XLA_FLAGS", "JAX_NUM_CPU_DEVICES", "GLIBC_TUNABLES", "OMP_NUM_THREADS")
            if k in os.environ
        },
    }


def git_commit() -> str:
    """'commit <hash>' of the source tree this package runs from (' + uncommitted changes' when
    git sees any), or 'no git checkout'."""
    root = provenance.repository_root()
    try:
        run = lambda *a: subprocess.run(  # noqa: E731
            ["git", "-C", str(root), *a], capture_output=True, text=True, timeout=10, check=True
        ).stdout.strip()
        head, dirty = (
            run("rev-parse", "--short=12", "HEAD"),
            run("status", "--porcelain", "--untracked-files=no", "--", "fabricjax", "experiments"),
        )
    except (OSError, subprocess.SubprocessError):
        return "no git checkout"
    return f"commit {head}" + (" + uncommitted changes" if dirty else "")


FINGERPRINT_DIGITS = 16  # hex digits of each fingerprint a results file records


class FingerprintKind(NamedTuple):
    """One thing a results file fingerprints: how its header lists it and how a note that it changed names it."""

    listed: str
    changed: str


# What `fingerprints` records, by its key, in the order results list them.
FINGERPRINT_KINDS = {
    "code": FingerprintKind("code", "the code that computes it"),
    "simulator": FingerprintKind("simulator", "the simulator or its estimates"),
    "data": FingerprintKind("recorded data", "the data"),
}


def simulated_data() -> str:
    """What decides a preset's simulated data besides the preset: the code that turns a scene into
    an archive (`source.simulator`) and the simulator's estimates in force (`sim.estimates.fingerprint`)."""
    return hashlib.sha256(f"{source.simulator()}\0{estimates.fingerprint()}".encode()).hexdigest()


def fingerprints(module: str, data: str | None) -> dict[str, str | None]:
    """What decides the numbers `module` computes besides its command (study, preset, seeds, rows,
    --set), as every results file (`header`) and `reproduce`'s manifest record it: "code", the
    modules `module` runs, without the simulator (`source.without_simulator`), so that an edit of a
    figure or of another study's module leaves it current; then the data's (`data_fingerprints`)."""
    prints = {"code": source.without_simulator([module])[:FINGERPRINT_DIGITS], **data_fingerprints(data)}
    return {kind: prints[kind] for kind in FINGERPRINT_KINDS}


def data_fingerprints(data: str | None) -> dict[str, str | None]:
    """The fingerprints of what a run read, the same for every module: "data", recorded data's
    contents (`data`: `DatasetIndex.content_hash`), None for a preset's simulated data, which
    "simulator" decides instead (`simulated_data`), None on recorded data."""
    return {"simulator": simulated_data()[:FINGERPRINT_DIGITS] if data is None else None, "data": data}


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
        with atomic_open(path, "w", what="a results file") as f:
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


def results_path(results=None) -> Path:
    return workspace.results_dir(results)


def utc_now() -> str:
    """The time results files record: '2026-11-25 10:55 UTC'."""
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


SAMPLES = ".samples.json"  # the suffix of a study's per-sample records beside its results JSON


def write(
    results,
    doc: dict[str, Any],
    markdown: Callable[[dict[str, Any]], str] | None,
    figures: Sequence[Path | None] = (),
    samples: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Write `doc` as results/<study>.json and `markdown(doc)` (None: no Markdown) as
    results/<study>.md, atomically, and `samples` (None: none) as results/<study>`SAMPLES`;
    `figures` (drawn into the same folder; None: not drawn) are listed by file name under the
    document's "figures" key first, which is how the Markdown and `reproduce` know a study's figures."""
    out = results_path(results)
    doc["figures"] = [Path(f).name for f in figures if f is not None]
    replaced = replacing(out / f"{doc['study']}.json", doc)
    if replaced:
        print(f"note: {replaced}", file=sys.stderr, flush=True)
    with atomic.together():  # both files, or neither (a study drawing figures holds them in its own block)
        if markdown is not None:
            write_text(out / f"{doc['study']}.md", markdown(doc))
        write_json(out / f"{doc['study']}.json", doc)
        if samples is not None:
            write_json(out / f"{doc['study']}{SAMPLES}", samples)
    return doc


def replacing(path: Path, doc: dict[str, Any]) -> str | None:
    """What `doc` replaces in words where the results at `path` are of another preset or other
    data (a user's run over the install check's, say), else None: a replaced run is said, not silent."""
    try:
        old = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(old, dict):
        return None

    def of(d: dict[str, Any]) -> str:
        return f"preset {d.get('preset')} on {(d.get('dataset') or {}).get('folder', 'its data')}"

    if of(old) == of(doc):
        return None
    return (
        f"{workspace.shown(path)} held the results of {of(old)}; this run's, of {of(doc)}, replace them"
        " (--results=DIR keeps both)"
    )


def header(study: str, *, module: str, command: str | None, data: str | None = None, **fields) -> dict[str, Any]:
    """The first fields of every results JSON: what ran (`study`; `module`: the module that computes
    it, whose code `fingerprints` covers; `command`: the command line, None when called from
    Python), from which code and with which `fingerprints` (`data`: recorded data's contents, None
    for simulated data), when and on which machine, then `fields`."""
    return {
        "study": study,
        "command": command,
        "code": git_commit(),
        "module": module,
        "fingerprints": fingerprints(module, data),
        "date": utc_now(),
        "machine": machine(),
        **fields,
    }
