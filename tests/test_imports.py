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
