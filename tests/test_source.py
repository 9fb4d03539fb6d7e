"""The code fingerprints: each covers the modules that compute a thing, so an edit stales exactly
what it can move (a figure's code nothing, a model constant every training result, the simulator
the simulated data), and a cache made by other code is not reused."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from fabricjax import source

REPO = Path(__file__).resolve().parents[1]
ABLATION = ["fabricjax.studies.paper.ablation"]


def test_a_closure_follows_imports_and_leaves_out_the_views():
    study = source.closure(ABLATION)
    assert {"fabricjax.model", "fabricjax.training.train", "fabricjax.features.welch", "fabricjax.config"} <= set(study)
    assert not set(source.VIEWS) & set(study)
    assert "fabricjax.sim.minsight" in study  # the study simulates its data where it has none
    assert not any(m.startswith("fabricjax.sim") for m in source.closure(ABLATION, (*source.VIEWS, source.SIMULATOR)))
    assert "fabricjax.model" not in source.closure(["fabricjax.sim.dataset"])


def _fingerprints(package: Path) -> dict[str, str]:
    code = (
        "import json; from fabricjax import source; print(json.dumps({"
        "'ablation': source.without_simulator(['fabricjax.studies.paper.ablation']), "
        "'simulator': source.simulator(), "
        "'features': source.fingerprint(['fabricjax.features.extract']), "
        "'views': source.views()}))"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=package, capture_output=True, text=True, check=True)
    return eval(out.stdout)  # noqa: S307 (our own JSON of strings)


@pytest.fixture(scope="module")
def copy_of_the_package(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("package")
    shutil.copytree(REPO / "fabricjax", root / "fabricjax", ignore=shutil.ignore_patterns("__pycache__"))
    return root


@pytest.mark.parametrize(
    "module, before, after, moves",
    [
        ("reporting/plots.py", "def ", "def _unused_helper():\n    return 1\n\n\ndef ", {"views"}),
        ("studies/pages/ablation.py", "def ", "def _unused_helper():\n    return 1\n\n\ndef ", {"views"}),
        ("model.py", "\nRESCALE_EPS = ", "\nRESCALE_EPS = 2 * ", {"ablation"}),
        ("sim/texture.py", "\nimport ", "\nUNUSED_CONSTANT = 1\nimport ", {"simulator"}),
        ("features/welch.py", "\ndef ", "\nUNUSED_CONSTANT = 1\n\n\ndef ", {"ablation", "features"}),
        ("model.py", '"""', '"""A docstring said otherwise.\n\n', set()),
    ],
)
def test_an_edit_moves_exactly_the_fingerprints_of_what_runs_it(copy_of_the_package, module, before, after, moves):
    path = copy_of_the_package / "fabricjax" / module
    original = path.read_text()
    assert before in original
    today = _fingerprints(copy_of_the_package)
    try:
        path.write_text(original.replace(before, after, 1))
        edited = _fingerprints(copy_of_the_package)
    finally:
        path.write_text(original)
    assert {k for k in today if today[k] != edited[k]} == moves
