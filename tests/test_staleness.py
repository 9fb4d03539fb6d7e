"""Staleness by construction: results record the fingerprints of what decides them (the code that
computes them without comments and docstrings, the simulator and its estimates in force, the
data), and `reproduce --check`, REPORT.md and README's results block flag the studies whose
fingerprints no longer match today's: exactly those an edit can move."""

import dataclasses
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from fabricjax import sim, source
from fabricjax.errors import UserError
from fabricjax.reporting import results_files
from fabricjax.sim import estimates
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents
from fabricjax.studies.diagnostics import probe
from fabricjax.studies.release import reproduce, reproduce_plan, reproduce_readme, reproduce_report, staleness

REPO = Path(__file__).resolve().parents[1]
PLAN = (reproduce_plan.Step("probe", rows=("proprio",)), reproduce_plan.Step("day_shift", rows=("proprio",)))


@pytest.fixture(scope="module")
def published(tmp_path_factory):
    """A results folder as `reproduce` writes it: the probe and the day shift (which reads the
    probe's results) on the smoke preset, a few seconds."""
    root = tmp_path_factory.mktemp("staleness")
    sim.ensure_dataset("smoke", root / "ws", streams=("audio", "proprio"), progress=False)
    where = Location(workdir=root / "ws", results=root / "results", command="test")
    reproduce.run(preset="smoke", plan=PLAN, where=where, say=lambda s: None)
    return where


def _check_command(where: Location, *args: str) -> subprocess.CompletedProcess:
    cmd = [
        sys.executable,
        "-m",
        "experiments.reproduce",
        "--check",
        f"--results={where.results}",
        f"--workdir={where.workdir}",
        *args,
    ]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300, cwd=REPO)


def test_the_code_fingerprint_ignores_comments_docstrings_and_blank_lines():
    code = "def f(x):\n    return x + 1  # one more\n"
    documented = (
        '"""A module."""\n\n# a note\ndef f(x):\n    """Add one."""\n\n    return x + 1  # one more, said again\n'
    )
    assert source.executed(documented) == source.executed(code) == "def f(x):\n    return x + 1\n"
    assert source.executed('def f(x):\n    s = "kept: a value"\n    return x + 2\n') != source.executed(code)


def test_every_results_file_records_the_fingerprints(published):
    doc = json.loads((published.results / "probe.json").read_text())
    assert doc["module"] == probe.__name__ == "fabricjax.studies.diagnostics.probe"
    # simulated data: decided by the probe's code, the simulator with its estimates and the preset
    assert doc["fingerprints"] == results_files.fingerprints(probe.__name__, None) == staleness.today("probe", None)
    assert documents.fingerprints_markdown(doc["fingerprints"]) in (published.results / "probe.md").read_text()
    manifest = json.loads((published.results / reproduce_plan.MANIFEST).read_text())
    assert manifest["probe"]["fingerprints"] == doc["fingerprints"] and manifest["probe"]["commit"] == doc["code"]


def test_an_unchanged_state_lists_nothing_stale(published):
    said = []
    assert staleness.check(published, say=said.append) == {}
    assert said[0].startswith("reproduce --check: 0 of the 2 studies of ")
    report = (published.results / reproduce_plan.REPORT).read_text()
    assert "stale since" not in report.lower()
    done = _check_command(published)
    assert done.returncode == 0, done.stderr
    assert "0 of the 2 studies" in done.stdout


def test_check_of_named_studies_checks_those_and_an_unknown_name_is_a_one_line_error(published):
    said = []
    assert staleness.check(published, say=said.append, studies=["day_shift"]) == {}
    assert said[0].startswith("reproduce --check: 0 of the 1 studies of ")
    with pytest.raises(UserError, match=r"--studies: unknown studies \['ablatoin'\]; choose from ablation, probe, "):
        staleness.check(published, studies=["ablatoin"])
    done = _check_command(published, "--studies=ablatoin")
    assert done.returncode == 2 and done.stdout == "", done.stderr
    assert done.stderr.startswith("error: --studies: unknown studies ['ablatoin']") and done.stderr.count("\n") == 1


def test_a_changed_estimate_marks_every_study_stale_in_check_and_report(published):
    manifest = json.loads((published.results / reproduce_plan.MANIFEST).read_text())
    estimates.override({"SERVO_TONE_PA": estimates.ESTIMATES["SERVO_TONE_PA"].value * 2})
    try:
        said = []
        notes = staleness.check(published, say=said.append)
        stale_report = reproduce_report.write_report(
            published.results / "STALE.md", manifest, "smoke", None, "test", 1.0, 0
        )
        report = stale_report.read_text()
        stale_report.unlink()  # a report under another name would be checked as a results file of its own
    finally:
        estimates.override({})
    since = f"stale since {manifest['probe']['commit']}"
    assert notes == {
        "probe": f"{since}: the simulator or its estimates changed",
        "day_shift": f"{since}: the simulator or its estimates changed",
    }
    text = "\n".join(said)
    assert (
        f"probe       {notes['probe']}: " in text and f"{published.results / 'probe.md'}" in text
    )  # each stale study's files
    assert "reruns what is stale" in text and "--preset=smoke" in text
    assert (
        f"**{notes['probe']}**" in report and f"> **S{notes['day_shift'][1:]}**" in report
    )  # the summary and the study's section
    assert staleness.check(published, say=lambda s: None) == {}  # the registry's values again: nothing stale


def _edit(monkeypatch, module: str) -> None:
    """As if `module`'s code had changed: its executed text hashes otherwise."""
    unedited = source._executed_hash
    monkeypatch.setattr(source, "_executed_hash", lambda m: "edited" if m == module else unedited(m))


def test_changed_code_marks_the_studies_stale_and_the_reader_of_a_rerun_study(published, monkeypatch):
    _edit(monkeypatch, "fabricjax.sequences.data")
    notes = staleness.stale(json.loads((published.results / reproduce_plan.MANIFEST).read_text()), None)
    assert list(notes) == ["probe", "day_shift"]
    assert all(n.endswith(": the code that computes it changed") for n in notes.values())
    monkeypatch.undo()
    manifest = json.loads((published.results / reproduce_plan.MANIFEST).read_text())
    manifest["probe"]["key"] = "0" * 16  # the probe rerun since: the day shift read the results of another probe
    notes = staleness.stale(manifest, None)
    assert notes["day_shift"].endswith(": the probe study it reads changed")


def test_check_exits_1_on_results_of_other_code_and_readme_says_stale(published, tmp_path):
    results = tmp_path / "results"
    shutil.copytree(published.results, results)
    manifest = json.loads((results / reproduce_plan.MANIFEST).read_text())
    keys: dict[str, str] = {}
    for study in ("probe", "day_shift"):  # as a run of other code would have recorded them
        e = manifest[study]
        e["fingerprints"]["code"] = "0" * 16
        e["key"] = keys[study] = staleness.step_key(
            reproduce_plan.Step(**e["step"]), e["preset"], e["overrides"], e["fingerprints"], keys.get("probe", "")
        )
    (results / reproduce_plan.MANIFEST).write_text(json.dumps(manifest))
    done = _check_command(Location(workdir=published.workdir, results=results))
    assert done.returncode == 1, done.stderr
    assert "2 of the 2 studies" in done.stdout and done.stdout.count(": the code that computes it changed: ") == 2
    assert str(results / "day_shift.md") in done.stdout
    head = {
        **json.loads((REPO / "results" / reproduce_plan.HEADLINE).read_text()),
        "stale": {reproduce_plan.title("probe"): "stale since commit abc: the code changed"},
    }
    block = reproduce_readme.readme_block(head)
    assert (
        f"**Stale**, not today's numbers: {reproduce_plan.title('probe')} (stale since commit abc: the code changed)"
        in block
    )


def test_check_of_a_folder_without_a_manifest_is_a_one_line_error(tmp_path):
    done = _check_command(Location(workdir=tmp_path / "ws", results=tmp_path / "nothing"))
    assert (
        done.returncode == 2
        and done.stderr.strip().count("\n") == 0
        and "no manifest of experiments.reproduce" in done.stderr
    )


def test_other_results_files_are_checked_by_the_fingerprints_their_results_json_records(tmp_path):
    """A study run alone, a sweep or a benchmark is not in the manifest: the fingerprints its results
    JSON records decide, and one that records none is stale (nothing says what it was computed from).
    A REPORT.md in a folder below gathers studies that are checked by their own files."""
    prints = results_files.fingerprints(probe.__name__, None)

    def results_file(name: str, doc: dict) -> None:
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).with_suffix(".md").write_text(f"# {name}\n")
        (tmp_path / name).with_suffix(".json").write_text(json.dumps(doc))

    results_file("cost", {"code": "commit abc123 + uncommitted changes"})
    results_file("sweeps/sweep", {"code": "commit abc123", "module": probe.__name__, "fingerprints": prints})
    results_file("palm", {"module": probe.__name__, "fingerprints": {**prints, "code": "0" * 16}})
    results_file("gone", {"module": "fabricjax.studies.gone", "fingerprints": prints})
    (tmp_path / "sweeps" / "REPORT.md").write_text("# Report\n")
    found = staleness.other_stale(tmp_path, {})
    assert set(found) == {str(tmp_path / f"{f}.md") for f in ("cost", "palm", "gone")}
    assert (
        found[str(tmp_path / "cost.md")]
        == "stale since commit abc123: it records no fingerprints of the code that computed it"
    )
    assert found[str(tmp_path / "palm.md")] == "stale: the code that computes it changed"
    assert found[str(tmp_path / "gone.md")] == "stale: the module that computed it, fabricjax.studies.gone, is gone"


def test_the_fingerprints_are_recorded_and_listed_as_their_kinds_say():
    prints = results_files.fingerprints(probe.__name__, None)
    assert list(prints) == list(results_files.FINGERPRINT_KINDS) == ["code", "simulator", "data"]
    assert documents.fingerprints_markdown(prints) == (
        f"- fingerprints: code `{prints['code']}`, simulator `{prints['simulator']}`"
    )
    recorded = results_files.fingerprints(probe.__name__, "d" * 16)
    assert recorded == {"code": prints["code"], "simulator": None, "data": "d" * 16}


def _plan_manifest(data: str | None) -> dict:
    """A manifest of every study of the plan as a run of today's code on `data` would record it."""
    manifest: dict = {}
    for step in reproduce_plan.PLAN:
        prints = staleness.today(step.study, data)
        upstream = staleness.upstream_key(step.study, {s: e["key"] for s, e in manifest.items()}, {})
        manifest[step.study] = {
            "key": staleness.step_key(step, "smoke", {}, prints, upstream),
            "step": dataclasses.asdict(step),
            "preset": "smoke",
            "overrides": {},
            "fingerprints": prints,
            "commit": "commit abc",
            "finished": "today",
        }
    return manifest


def _results_file(folder: Path, name: str, module: str, data: str | None) -> None:
    """A results file outside the manifest (a sweep, the bench) as today's code of `module` writes it."""
    (folder / f"{name}.md").write_text(f"# {name}\n")
    doc = {"code": "commit abc", "module": module, "fingerprints": results_files.fingerprints(module, data)}
    (folder / f"{name}.json").write_text(json.dumps(doc))


@pytest.mark.parametrize("view", source.view_modules())
def test_a_rendering_only_change_leaves_every_study_fresh(view, monkeypatch, tmp_path):
    _results_file(tmp_path, "sweep", "fabricjax.studies.diagnostics.sweep", None)
    _results_file(tmp_path, "bench", "fabricjax.bench.suite", None)
    manifest = _plan_manifest(None)
    _edit(monkeypatch, view)
    assert staleness.stale(manifest, None) == {} and staleness.other_stale(tmp_path, manifest) == {}


def test_a_model_constant_stales_exactly_the_studies_whose_code_reads_it(monkeypatch, tmp_path):
    _results_file(tmp_path, "sweep", "fabricjax.studies.diagnostics.sweep", None)
    _results_file(tmp_path, "bench", "fabricjax.bench.suite", None)
    _results_file(tmp_path, "camera_frames_alone", "fabricjax.studies.diagnostics.camera_frames", None)
    manifest = _plan_manifest(None)
    _edit(monkeypatch, "fabricjax.model")  # model.RESCALE_EPS, say
    notes = staleness.stale(manifest, None)
    reads = [s for s, m in reproduce_plan.STUDIES.items() if "fabricjax.model" in source.closure([m.__name__])]
    assert "ablation" in notes and list(notes) == reads and "camera_frames" not in notes
    assert notes["ablation"] == "stale since commit abc: the code that computes it changed"
    assert set(staleness.other_stale(tmp_path, manifest)) == {str(tmp_path / "sweep.md"), str(tmp_path / "bench.md")}


def test_a_simulator_estimate_stales_only_the_studies_on_simulated_data(tmp_path):
    simulated, recorded = _plan_manifest(None), _plan_manifest("d" * 16)
    _results_file(tmp_path, "sweep", "fabricjax.studies.diagnostics.sweep", None)
    _results_file(tmp_path, "sweep_recorded", "fabricjax.studies.diagnostics.sweep", "d" * 16)
    estimates.override({"SERVO_TONE_PA": estimates.ESTIMATES["SERVO_TONE_PA"].value * 2})
    try:
        on_simulated, on_recorded = staleness.stale(simulated, None), staleness.stale(recorded, "d" * 16)
        others = staleness.other_stale(tmp_path, {})
    finally:
        estimates.override({})
    assert list(on_simulated) == list(reproduce_plan.STUDIES) and on_recorded == {}
    assert set(on_simulated.values()) == {"stale since commit abc: the simulator or its estimates changed"}
    assert list(others) == [str(tmp_path / "sweep.md")]


def test_the_decision_study_is_given_the_ablation_rows_labels(tmp_path):
    """decide.png titles name the ablation's rows as its tables print them (`display_name`), not by
    the rows' internal names."""
    rows = [
        {"name": name, "checkpoint": f"ckpt/{name}", "display_name": f"label of {name}"}
        for name in reproduce_plan.DECIDE_ROWS
    ]
    (tmp_path / "ablation.json").write_text(json.dumps({"rows": rows}))
    folders, names = reproduce._decide_checkpoints(tmp_path, reproduce_plan.DECIDE_ROWS)
    assert folders == [f"ckpt/{n}" for n in reproduce_plan.DECIDE_ROWS]
    assert names == [f"label of {n}" for n in reproduce_plan.DECIDE_ROWS]


def test_the_published_files_are_found_under_one_repository_root():
    from fabricjax.store import provenance
    from fabricjax.studies.diagnostics import sensitivity

    root = provenance.repository_root()
    assert (root / "fabricjax" / "__init__.py").is_file()
    assert reproduce_plan.PUBLISHED_MANIFEST.parent == sensitivity.PUBLISHED.parent
    assert reproduce_plan.PUBLISHED_MANIFEST.parent == root / "results"
