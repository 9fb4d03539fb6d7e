"""The documents stay true by construction: README's results block is the one the published
results render, no measured number sits outside it, and no tracked document names a path of the
machine that wrote it."""

import json
import re
from pathlib import Path

import numpy as np

from fabricjax.store import workspace
from fabricjax.studies.machinery import findings
from fabricjax.studies.release import reproduce_plan, reproduce_readme

REPO = Path(__file__).parents[1]
DOCUMENTS = [REPO / "README.md", REPO / "WORKSPACE.md", REPO / "CHANGELOG.md", *sorted((REPO / "docs").glob("*.md"))]


def _readme_parts() -> tuple[str, str, str]:
    text = (REPO / "README.md").read_text()
    before, rest = text.split(reproduce_readme.README_BEGIN)
    block, after = rest.split(reproduce_readme.README_END)
    return before, reproduce_readme.README_BEGIN + block + reproduce_readme.README_END, after


def test_readme_results_block_is_what_the_published_results_render():
    head = json.loads((REPO / "results" / reproduce_plan.HEADLINE).read_text())
    _, block, _ = _readme_parts()
    assert block == reproduce_readme.readme_block(head), (
        "README's results block differs from results/headline.json: rerun experiments.reproduce"
    )
    ablation_md = (REPO / "results" / "ablation.md").read_text()
    for row in head["rows"]:  # the same numbers as the published table
        assert f"| {row['ours']} |" in ablation_md, row


def test_no_measured_number_outside_the_generated_block():
    before, _, after = _readme_parts()
    outside = before + after
    assert not re.findall(r"\d\s?(%|pp\b)", outside), re.findall(r".{30}\d\s?(?:%|pp\b).{10}", outside)


def test_documents_are_short():
    assert len((REPO / "README.md").read_text().splitlines()) <= 250
    assert len((REPO / "WORKSPACE.md").read_text().splitlines()) <= 200


def test_no_tracked_document_or_result_names_a_machine_path():
    files = [*DOCUMENTS, *[p for p in (REPO / "results").rglob("*") if p.suffix in (".md", ".json", ".log", ".txt")]]
    absolute = re.compile(r"(?<![\w.~-])/(work|root|tmp|home|Users|mnt|opt|var)/")
    found = [
        f"{p.relative_to(REPO)}:{i}"
        for p in files
        if p.exists()
        for i, line in enumerate(p.read_text().splitlines(), 1)
        if absolute.search(line)
    ]
    assert not found, found


def test_documents_link_only_to_files_that_exist():
    for doc in DOCUMENTS:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", doc.read_text()):
            if not re.match(r"[a-z]+://", target):
                assert (doc.parent / target).exists(), (
                    f"{doc.relative_to(REPO)} links to {target}, which does not exist"
                )


def test_results_name_paths_inside_the_working_directory_relatively(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert (
        workspace.shown(tmp_path / "workspace" / "checkpoints" / "ablation" / "internal-1")
        == "workspace/checkpoints/ablation/internal-1"
    )
    assert workspace.shown("workspace/checkpoints/x") == "workspace/checkpoints/x"
    outside = tmp_path.parent / "elsewhere"
    assert workspace.shown(outside) == str(outside)


def test_a_collapsed_model_is_named_not_measured():
    one_class = np.zeros((5, 100), int)
    assert findings.collapse_text(findings.collapsed(one_class)) == " (collapsed to class 0: 5 of 5 seeds)"
    mixed = np.tile(np.arange(4), (2, 25))
    assert findings.collapse_text(findings.collapsed(mixed)) == ""
    nearly = np.zeros(100, int)
    nearly[:4] = 3  # 96 % one class: collapsed; a single model names no seeds
    assert findings.collapse_text(findings.collapsed(nearly)) == " (collapsed to class 0)"
    nearly[:6] = 3
    assert findings.collapse_text(findings.collapsed(nearly)) == "" and findings.collapsed([]) == [None]


def test_the_majority_baseline_comes_from_the_splits_own_labels():
    assert findings.majority([2, 2, 1, -1, 0]) == {
        "label": 2,
        "accuracy": 50.0,
        "known": 4,
    }  # unknown labels (-1) left out
    assert findings.majority([1, 0])["label"] == 0  # a tie: the lowest label
    assert findings.majority([-1, -1]) is None and findings.majority_cell(None) == "–"
    assert findings.majority_cell(findings.majority([1, 1, 0]), "level") == "66.67 (level 1)"
    # collapse counts the sequences whose label is known: one seed answers 3 for every known one
    assert findings.collapsed([[0, 3, 3, 3]], [-1, 1, 1, 1]) == [3] and findings.collapsed([[0, 3, 3, 3]]) == [None]
    assert findings.collapse_text([3], "level") == " (collapsed to level 3)"
    assert findings.above_majority([0.61, 0.60], {"label": 1, "accuracy": 60.64, "known": 100}) is False
    assert findings.above_majority([0.61, 0.61], None) is None


def _fenced(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", (REPO / "README.md").read_text(), re.S)


def test_readme_starts_with_the_install_and_test_commands_ci_runs():
    first = _fenced("bash")[0]
    commands = [line for line in first.splitlines() if line and not line.startswith("#")]
    assert commands[0].endswith("pip install -e . && python -m experiments.ablation --seeds=5")
    assert commands[1].endswith('pip install -e ".[test]" && python -m pytest')
    ci = (REPO / ".ci" / "run").read_text()
    assert 'pip install -q -e ".[test]"' in ci and ci.rstrip().endswith("&& python -m pytest")


def test_the_readme_smoke_check_runs_as_written_and_prints_what_it_shows(tmp_path):
    """README's one-minute check, run verbatim (in a scratch workspace): every line README shows
    of its output is printed, '...' standing for the measured parts."""
    import os
    import subprocess
    import sys

    [command] = [c.strip() for c in _fenced("bash")[1:] if "--preset=smoke" in c]
    args = command.split()
    assert args[:3] == ["python", "-m", "experiments.ablation"]
    env = {
        k: v for k, v in os.environ.items() if k != workspace.ENV_VAR
    }  # the default workspace: ./workspace of the scratch folder
    env.update(JAX_PLATFORMS="cpu", JAX_DISABLE_MOST_OPTIMIZATIONS="1")
    out = subprocess.run(
        [sys.executable, *args[1:]], env=env, cwd=tmp_path, capture_output=True, text=True, timeout=300, check=True
    )
    printed = [line.split("] ", 1)[-1] for line in (out.stdout + out.stderr).replace("\r", "\n").splitlines()]
    shown = _fenced("text")[0].strip().splitlines()
    for line in shown:
        pattern = re.escape(line).replace(re.escape("..."), ".+")
        assert any(re.fullmatch(pattern, p) for p in printed), (line, printed[-8:])
