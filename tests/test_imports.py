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
import fabricjax
names = sorted(m.name for m in pkgutil.walk_packages(fabricjax.__path__, "fabricjax."))
for name in names:
    importlib.import_module(name)
from fabricjax import runtime
print(json.dumps({
    "modules": names,
    "experiments": sorted(m for m in sys.modules if m == "experiments" or m.startswith("experiments.")),
    "threefry_configured": runtime._threefry_unrolled is not None,
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
        "fabricjax.studies.tools.stream",
    } <= set(doc["modules"])
    assert doc["experiments"] == [], doc["experiments"]
    assert not doc["threefry_configured"]  # importing the library leaves JAX as it is


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


# Subpackages by layer: a module imports only its own subpackage, the package's modules and the
# subpackages of lower layers. The studies and the benchmarks are the top, side by side.
LOWER = {"features": set(), "sim": set(), "bench": {"features", "sim"}, "studies": {"features", "sim"}}


def test_no_subpackage_imports_one_beside_or_above_it():
    subpackages = {p.name for p in (ROOT / "fabricjax").iterdir() if (p / "__init__.py").is_file()}
    assert subpackages == set(LOWER), "give the new subpackage its layer in LOWER"
    found = []
    for path in sorted((ROOT / "fabricjax").rglob("*.py")):
        parts = path.relative_to(ROOT / "fabricjax").parts
        own = parts[0] if len(parts) > 1 else None
        allowed = {own} | LOWER.get(own, set()) if own else {"features", "sim"}
        for name in _imports(path):
            target = name.split(".")[1] if name.count(".") else None
            if target in subpackages and target not in allowed:
                found.append(f"{path.relative_to(ROOT)}: {name}")
    assert found == []
