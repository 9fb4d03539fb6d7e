"""Dependencies point down: no `fabricjax` module imports `experiments` (the commands), and
importing the library configures nothing in JAX (that is `fabricjax.runtime.configure_jax`)."""

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# In a fresh interpreter: import every module under fabricjax, then report what came along.
CODE = """
import importlib, json, pkgutil, sys
from jax._src import monitoring
import fabricjax
names = sorted(m.name for m in pkgutil.walk_packages(fabricjax.__path__, "fabricjax."))
for name in names:
    importlib.import_module(name)
from fabricjax import runtime
print(json.dumps({
    "modules": names,
    "experiments": sorted(m for m in sys.modules if m == "experiments" or m.startswith("experiments.")),
    "threefry_configured": runtime._threefry_unrolled is not None,
    "jax_listeners": len(monitoring._event_duration_secs_listeners),
}))
"""


def test_no_library_module_imports_the_commands():
    env = {
        **os.environ,
        "JAX_PLATFORMS": "cpu",
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
    }
    out = subprocess.run([sys.executable, "-c", CODE], env=env, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    doc = json.loads(out.stdout.strip().splitlines()[-1])
    assert {
        "fabricjax.cli",
        "fabricjax.runtime",
        "fabricjax.bench.torch_twin",
        "fabricjax.bench.suite",
        "fabricjax.studies.diagnostics.stream",
    } <= set(doc["modules"])
    assert doc["experiments"] == [], doc["experiments"]
    assert not doc["threefry_configured"]  # importing the library leaves JAX as it is
    assert doc["jax_listeners"] == 0  # a run listens to JAX's compile events while it runs (`train.TimeAccount`)


def test_no_library_module_imports_the_commands_even_lazily():
    """Imports inside functions and `importlib.import_module("experiments...")` count too."""
    found = []
    for path in sorted((ROOT / "fabricjax").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""] if node.level == 0 else []
            elif isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", None)) in (
                "import_module",
                "__import__",
            ):
                names = [a.value for a in node.args[:1] if isinstance(a, ast.Constant) and isinstance(a.value, str)]
            else:
                continue
            found += [f"{path.relative_to(ROOT)}:{node.lineno}: {n}" for n in names if n.split(".")[0] == "experiments"]
    assert found == []


def _imports(path: Path) -> list[str]:
    """The `fabricjax` modules `path` imports, anywhere in it, as dotted names."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("fabricjax"):
            found += [f"{node.module}.{a.name}" for a in node.names] if node.module == "fabricjax" else [node.module]
        elif isinstance(node, ast.Import):
            found += [a.name for a in node.names if a.name.startswith("fabricjax")]
    return found


# Subpackages by layer, in the order of the data path: a module imports only its own subpackage, the
# package's top-level modules and the subpackages of lower layers. The benchmarks time the real
# programs on synthetic data, and the studies are the top: a study's plan times its rows with them.
LOWER = {
    "store": set(),
    "sim": {"store"},
    "features": {"store"},
    "importers": {"store", "features"},
    "sequences": {"store", "features"},
    "training": {"store", "features", "sequences"},
    "reporting": {"store", "sim"},
    "inference": {"store", "features", "sequences", "training", "reporting"},
    "bench": {"store", "sim", "features", "importers", "sequences", "training", "reporting", "inference"},
    "studies": {"store", "sim", "features", "sequences", "training", "reporting", "inference", "bench"},
}
# The package's top-level modules (the core: config, presets, the model, the process) read only the
# storage, features and sequences below them.
TOP_LEVEL = {"store", "features", "sequences"}


def test_no_subpackage_imports_one_beside_or_above_it():
    subpackages = {p.name for p in (ROOT / "fabricjax").iterdir() if (p / "__init__.py").is_file()}
    assert subpackages == set(LOWER), "give the new subpackage its layer in LOWER"
    found = []
    for path in sorted((ROOT / "fabricjax").rglob("*.py")):
        parts = path.relative_to(ROOT / "fabricjax").parts
        own = parts[0] if len(parts) > 1 else None
        allowed = {own} | LOWER.get(own, set()) if own else TOP_LEVEL
        for name in _imports(path):
            target = name.split(".")[1] if name.count(".") else None
            if target in subpackages and target not in allowed:
                found.append(f"{path.relative_to(ROOT)}: {name}")
    assert found == []


def _imported_modules(path: Path, modules: set[str]) -> set[str]:
    """The package modules `path` imports, anywhere in it: `from fabricjax.store import archive` is the
    archive module, `from fabricjax.store.archive import read` too."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("fabricjax"):
            names = [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names if a.name.startswith("fabricjax")]
        else:
            continue
        for name in names:
            while name and name not in modules:
                name = name.rpartition(".")[0]
            found |= {name} if name else set()
    return found


def test_no_import_circle():
    """No module reaches itself through the imports of the modules it imports, at any depth."""
    paths = {
        ".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__"): p
        for p in (ROOT / "fabricjax").rglob("*.py")
    }
    graph = {m: {t for t in _imported_modules(p, set(paths)) if not m.startswith(t)} for m, p in paths.items()}
    circles, state = [], {}

    def visit(m: str, trail: list[str]) -> None:
        state[m] = "open"
        for t in sorted(graph[m]):
            if state.get(t) == "open":
                circles.append(" -> ".join(trail[trail.index(t) :] + [m, t]) if t in trail else f"{m} -> {t}")
            elif t not in state:
                visit(t, trail + [m])
        state[m] = "done"

    for m in sorted(graph):
        if m not in state:
            visit(m, [])
    assert circles == []


# The studies' own folders: a leaf study imports what every study is built of (`machinery`) and the
# layers below, never another leaf study; the release tooling above them gathers the leaves.
LEAF_STUDIES = ("paper", "diagnostics")


def test_no_leaf_study_imports_another():
    studies = ROOT / "fabricjax" / "studies"
    found = []
    for folder in LEAF_STUDIES:
        for path in sorted((studies / folder).glob("*.py")):
            for name in _imports(path):
                parts = name.split(".")
                if parts[:2] == ["fabricjax", "studies"] and len(parts) > 2 and parts[2] in (*LEAF_STUDIES, "release"):
                    found.append(f"{path.relative_to(ROOT)}: {name}")
    assert found == []


def test_no_study_function_is_over_80_lines():
    """A study's function says one thing: a longer one is split by meaning (a page into its sections,
    a run into what it measures and what it writes)."""
    found = []
    for path in sorted((ROOT / "fabricjax" / "studies").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.end_lineno - node.lineno + 1 > 80:
                found.append(
                    f"{path.relative_to(ROOT)}:{node.lineno}: {node.name}, {node.end_lineno - node.lineno + 1}"
                )
    assert found == []
