"""The code that computes a thing, as a fingerprint: what keys results, checkpoints and caches.

A config names what a run computes, not the code that computes it: a change in how training
rounds (the image rotation's, for one) moves results and leaves every config as it was. So
everything that reuses what a run made keys it with the code as well: the simulated archives
(`sim.dataset`), the feature cache (`features.cache`), a study's checkpoint folders and every
results file's header.

Which code: the import closure of the module that computes the thing, the modules it imports at
any depth inside the package (imports inside functions included), each as it executes: without
comments, docstrings (a statement that is a string alone) and blank lines, so that a change of
documentation alone leaves everything current. A closure leaves out what does not decide the
numbers: the figures, the studies' pages and the Markdown (`VIEWS`), and, where the data is
keyed by its own content, the simulator. So a figure's edit reruns nothing, a simulator edit re-simulates and
retrains only what reads simulated data, and a model constant stales every result that trains.
Why the import closure rather than the lowered program: the host code around the program
(splits, standardisation, early stopping, the simulator in NumPy) decides the numbers as much
as the program does, and the closure is known without running or compiling anything, so
`reproduce --check` works on a fresh clone.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import io
import tokenize
from pathlib import Path
from typing import Iterable

_STATEMENT_START = (tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT, None)  # None: the module's first token


def executed(text: str) -> str:
    """The source `text` of a module without its comments, docstrings and blank lines (trailing
    spaces dropped): what the fingerprint hashes of it."""
    tokens = [t for t in tokenize.generate_tokens(io.StringIO(text).readline) if t.type != tokenize.NL]
    cut = []  # (start, end) of each comment and docstring, as (row, column)
    for k, t in enumerate(tokens):
        before = tokens[k - 1].type if k else None
        after = tokens[k + 1].type if k + 1 < len(tokens) else tokenize.ENDMARKER
        if t.type == tokenize.COMMENT or (
            t.type == tokenize.STRING and before in _STATEMENT_START and after in (tokenize.NEWLINE, tokenize.ENDMARKER)
        ):
            cut.append((t.start, t.end))
    lines = text.splitlines(keepends=True)
    starts = [0]
    for line in lines:
        starts.append(starts[-1] + len(line))
    kept, at = [], 0
    for (r0, c0), (r1, c1) in cut:
        begin, end = starts[r0 - 1] + c0, starts[r1 - 1] + c1
        kept.append(text[at:begin])
        at = end
    kept.append(text[at:])
    return "\n".join(line.rstrip() for line in "".join(kept).splitlines() if line.strip()) + "\n"


PACKAGE = Path(__file__).resolve().parent
# Modules that only present numbers (a package: every module in it): a closure does not descend into them.
VIEWS = (
    "fabricjax.reporting.plots",
    "fabricjax.reporting.results_files",
    "fabricjax.studies.machinery.documents",
    "fabricjax.studies.pages",
)
SIMULATOR = "fabricjax.sim"


@functools.cache
def _modules() -> dict[str, Path]:
    """Every module of the package by dotted name (a package by its own name)."""
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = ("fabricjax", *path.relative_to(PACKAGE).with_suffix("").parts)
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


@functools.cache
def _imports(module: str) -> frozenset[str]:
    """The package modules `module` imports anywhere in it: `from fabricjax.store import archive`
    is the archive module, `from fabricjax.store.archive import read` too, and a name a package
    re-exports (`from fabricjax.sim import simulate`) is the package's `__init__`, whose imports
    the closure then follows. A package's `__init__` that Python runs on the way to a submodule
    computes nothing of it, so it is not counted."""
    modules = _modules()
    found = set()
    for node in ast.walk(ast.parse(modules[module].read_text(), str(modules[module]))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("fabricjax"):
            names = [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names if a.name.startswith("fabricjax")]
        else:
            continue
        for name in names:
            while name not in modules:
                name = name.rpartition(".")[0]
            found.add(name)
    return frozenset(found - {module, "fabricjax"})


def is_module(name: str) -> bool:
    """`name` is a module of the package (a results file may name one since renamed)."""
    return name in _modules()


def _left_out(module: str, leave_out: Iterable[str]) -> bool:
    return any(module == m or module.startswith(m + ".") for m in leave_out)


def closure(roots: Iterable[str], leave_out: Iterable[str] = VIEWS) -> tuple[str, ...]:
    """The modules `roots` run, sorted: themselves and what they import at any depth, not
    descending into `leave_out` (modules or packages)."""
    leave_out = tuple(leave_out)
    seen, todo = set(), [r for r in roots if not _left_out(r, leave_out)]
    while todo:
        m = todo.pop()
        if m not in seen:
            seen.add(m)
            todo += [i for i in _imports(m) if not _left_out(i, leave_out)]
    return tuple(sorted(seen))


@functools.cache
def _executed_hash(module: str) -> str:
    return hashlib.sha256(executed(_modules()[module].read_text()).encode()).hexdigest()


def _hash(modules: Iterable[str]) -> str:
    """sha256 over `modules`: each one's name and what it executes."""
    h = hashlib.sha256()
    for m in modules:
        h.update(m.encode() + b"\0" + _executed_hash(m).encode() + b"\0")
    return h.hexdigest()


def fingerprint(roots: Iterable[str], leave_out: Iterable[str] = VIEWS) -> str:
    """sha256 over the modules `roots` run (`closure`): each one's name and what it executes."""
    return _hash(closure(roots, leave_out))


def view_modules() -> tuple[str, ...]:
    """Every module `VIEWS` names, each module of a package among them included, sorted."""
    return tuple(sorted(m for m in _modules() if _left_out(m, VIEWS)))


def views() -> str:
    """sha256 over the modules that only present numbers (`view_modules`), each alone: what a
    study's pages are drawn with besides its own module, whose code its results' fingerprint covers."""
    return _hash(view_modules())


TRAINING = ("fabricjax.training.train", "fabricjax.sequences.data")  # what trains a row from archives


def training() -> str:
    """The code that trains a row from archives, which keys a study's checkpoint folders."""
    return without_simulator(TRAINING)


SIMULATION = ("fabricjax.sim.trial", "fabricjax.store.archive")  # a scene to an archive on disk


def simulator() -> str:
    """The code that turns a scene into an archive: what decides a simulated archive besides its
    scene (which names the preset's trial, its effects and the estimates in force)."""
    return fingerprint(SIMULATION)


def without_simulator(roots: Iterable[str]) -> str:
    """The code of `roots` that computes from archives: the simulator left out, as the data's own
    fingerprint (its contents, or for simulated data `simulator` with the scene) stands for it."""
    return fingerprint(roots, (*VIEWS, SIMULATOR))
