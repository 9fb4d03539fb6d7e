"""Every example command the project shows runs: each `python -m experiments.<command> ...` line of
an experiments module's docstring, of a fabricjax module's docstring, of README.md and docs/*.md
(fenced blocks and inline code), and each `--flag=value` example a command's own `--help` gives
for that flag (in place of that flag's values in the command's first docstring example), parses
its flags and passes the command's own argument checks.

What a passing example proves: the command's flags parse (absl), the values pass every check the
command makes before its work begins (`--set` against the preset's `Config` and against the
fields a study's rows set, `--rows` against the study's rows and labels, `--seeds`, `--studies`,
`--unknown_labels`, `--train_seeds`, the estimate groups, ...), and the command reaches its work.
Each example runs in a process forked from one that imported the libraries once, in a scratch
directory, with `--workdir` and `--results` (and `experiments.estimates`' `--doc`) pointed at
temporary paths, and stops where its work would begin (`BOUNDARIES`: loading or simulating data,
simulating a scene (a training study's plan, printed before it trains, times one), reading an
archive or a results file, checking a results folder's fingerprints, restoring a checkpoint,
verifying a folder, reading a recording to import (its manifest, mapping, rig file or trial
folder), a benchmark): a full run takes minutes to hours, and what it reads (DIR, ARCHIVE, a
checkpoint, MANIFEST.csv) is a placeholder. Joining a run over several processes (`--distributed`)
is skipped, so such an example is checked as one process. An example that needs a screen (`--view`) is checked as
on a machine with one. Example commands that finish before any boundary (`--plan`,
`estimates --check`) run to the end. What it does not prove: that the data, checkpoints or files an
example names exist, or that the run after the boundary succeeds (the study tests do that).
"""

from __future__ import annotations

import ast
import json
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PREFIX = "python -m experiments."
COMMANDS = sorted(
    p.stem for p in (REPO / "experiments").glob("*.py") if p.stem not in ("__init__", "flags", "import_flags")
)
DOCUMENTS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
# Where a command's work begins, and what that work is: an example stops there (module docstring).
BOUNDARIES = {
    "fabricjax.studies.machinery.loading.load_dataset": "loads a study's data",
    "fabricjax.studies.machinery.loading.load_for_rows": "loads a study's data",
    "fabricjax.store.dataset_index.load_index": "indexes a data folder",
    "fabricjax.sim.dataset.ensure_dataset": "simulates a preset's dataset",
    "fabricjax.sim.trial.simulate": "simulates a trial",
    "fabricjax.sim.trial.procedure": "simulates a trial's motion",
    "fabricjax.store.archive.read_archive": "reads a trial archive",
    "fabricjax.training.train.restore": "restores a checkpoint",
    "fabricjax.store.integrity.verify": "verifies a folder of archives",
    "fabricjax.importers.manifest_file.read_manifest": "reads a manifest",
    "fabricjax.importers.mapping_file.read_toml": "reads a mapping or rig file",
    "fabricjax.importers.hand_folder.import_folder": "reads a trial folder",
    "fabricjax.studies.diagnostics.variant.read": "reads a results file",
    "fabricjax.studies.release.staleness.check": "checks a results folder's fingerprints",
    "fabricjax.bench.suite._torch_twin": "builds the PyTorch twin of the benchmarks",
    "fabricjax.studies.release.soak.as_processes": "runs the install check again and again",
}
# every benchmark function (of fabricjax.bench, .timing, .importers and acquisition): "runs a benchmark"
BENCHMARK_PREFIX = "bench_"
TIMEOUT_S = 120  # per example: one that reaches no boundary by then is reported
REFUSED = f"{PREFIX}ablation --set=backbone=tcn"  # the negative control: the ablation's rows set the backbone


def _command(text: str) -> str | None:
    """The example command in `text` (a line of a document or docstring), from `PREFIX` to its end:
    a trailing `# comment` and synopsis brackets (`[--view]`) dropped, None without one."""
    start = text.find(PREFIX)
    if start < 0:
        return None
    line = text[start:].split("&&")[0].split("  #")[0].split(" # ")[0]
    return re.sub(r"[\[\]]", "", line).strip()


def _joined(lines: list[str]) -> list[str]:
    """`lines` with shell continuations (a trailing backslash) joined."""
    out: list[str] = []
    for line in lines:
        if out and out[-1].endswith("\\"):
            out[-1] = out[-1][:-1].rstrip() + " " + line.strip()
        else:
            out.append(line)
    return out


def docstring_examples() -> list[tuple[str, str]]:
    """(where, command) of every docstring line of experiments/ and fabricjax/ modules that starts
    with an example command."""
    out = []
    for path in sorted([*(REPO / "experiments").glob("*.py"), *(REPO / "fabricjax").rglob("*.py")]):
        doc = ast.get_docstring(ast.parse(path.read_text())) or ""
        for line in _joined(doc.splitlines()):
            if line.strip().startswith(PREFIX):
                out.append((f"{path.relative_to(REPO)} docstring", _command(line)))
    return out


def document_examples() -> list[tuple[str, str]]:
    """(where, command) of every example command of README.md and docs/*.md: the lines of fenced
    code blocks, and inline code that starts with one."""
    out = []
    for path in DOCUMENTS:
        text = path.read_text()
        for block in re.findall(r"```[^\n]*\n(.*?)```", text, re.S):
            out += [(str(path.relative_to(REPO)), c) for line in _joined(block.splitlines()) if (c := _command(line))]
        prose = re.sub(r"```.*?```", "", text, flags=re.S)
        out += [
            (str(path.relative_to(REPO)), _command(span))
            for span in re.findall(r"`([^`\n]+)`", prose)
            if span.startswith(PREFIX)
        ]
    return out


def help_examples(command: str, helps: dict[str, str], base: str) -> list[tuple[str, str]]:
    """(where, command) for each flag of `command` whose `--help` text gives examples of itself
    (`--set=seq_len=100 ...`): `base` (a whole command line: the command's first docstring
    example, which gives what it requires) with that flag's examples instead of its own values."""
    out = []
    for name, text in helps.items():
        tokens = []
        for token in re.findall(rf"--{name}=\S+", text):
            token = token.rstrip(";,.)")
            tokens.append(shlex.split(token)[0] if token.count("'") % 2 == 0 else token)
        if tokens:
            kept = [t for t in shlex.split(base) if not t.startswith(f"--{name}=")]
            out.append((f"{PREFIX}{command} --help, --{name}", " ".join(shlex.quote(t) for t in kept + tokens)))
    return out


def base_example(command: str) -> str:
    """The first example of `command` its own module's docstring gives (the command alone without one)."""
    where = f"experiments/{command}.py docstring"
    return next(
        (c for w, c in docstring_examples() if w == where and c.split()[2] == f"experiments.{command}"),
        f"{PREFIX}{command}",
    )


def static_examples() -> list[tuple[str, str]]:
    return docstring_examples() + document_examples()


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory):
    """Every example's outcome, from one driver process (this file run as a script): about 15 s
    for some 100 distinct examples on 2 cores."""
    scratch = tmp_path_factory.mktemp("examples")
    jobs = {"examples": static_examples() + [("negative control", REFUSED)], "scratch": str(scratch)}
    env = {
        **os.environ,
        "JAX_PLATFORMS": "cpu",
        "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]),
    }
    done = subprocess.run(
        [sys.executable, __file__],
        input=json.dumps(jobs),
        capture_output=True,
        text=True,
        env=env,
        timeout=1800,
        cwd=scratch,
    )
    assert done.returncode == 0, done.stderr[-4000:]
    return json.loads(done.stdout.splitlines()[-1])


def _failures(results: list[dict]) -> list[str]:
    return [
        f"{r['where']}: `{r['command']}`: {r['outcome']}\n{r['output'][-1500:]}" for r in results if not r["passed"]
    ]


def test_every_documented_example_passes_its_commands_argument_checks(outcomes):
    documented = [r for r in outcomes if r["where"] != "negative control" and "--help" not in r["where"]]
    assert len(documented) >= 40  # the extraction found the examples
    failures = _failures(documented)
    assert not failures, "\n\n".join(failures)


def test_every_flag_help_example_passes_its_commands_argument_checks(outcomes):
    from_help = [r for r in outcomes if "--help" in r["where"]]
    assert any("--set=" in r["command"] for r in from_help)  # the shared --set help's examples are among them
    failures = _failures(from_help)
    assert not failures, "\n\n".join(failures)


def test_a_refused_example_is_caught(outcomes):
    """The harness is not vacuous: an example the command refuses fails, with its one-line error."""
    [control] = [r for r in outcomes if r["where"] == "negative control"]
    assert not control["passed"] and "error: the ablation study sets backbone per row itself" in control["output"]


def test_examples_are_extracted_from_docstrings_documents_and_continuations():
    assert (
        _command("    python -m experiments.stream [--print_every=10] [--view]   # also")
        == "python -m experiments.stream --print_every=10 --view"
    )
    assert (
        _command("pip install -e . && python -m experiments.ablation --seeds=5")
        == "python -m experiments.ablation --seeds=5"
    )
    assert _joined(["python -m experiments.cost --widths= \\", "    --modality_sets=internal"]) == [
        "python -m experiments.cost --widths= --modality_sets=internal"
    ]
    helps = {
        "set": "override ..., e.g. --set=seq_len=100 --set=compute_dtype=bfloat16; repeat this option",
        "grid": "e.g. --grid='a=1;2'",
    }
    assert help_examples("cost", helps, "python -m experiments.cost --seeds=5 --set=width=8") == [
        (
            "python -m experiments.cost --help, --set",
            "python -m experiments.cost --seeds=5 --set=seq_len=100 --set=compute_dtype=bfloat16",
        ),
        (
            "python -m experiments.cost --help, --grid",
            "python -m experiments.cost --seeds=5 --set=width=8 '--grid=a=1;2'",
        ),
    ]
    assert (
        base_example("latents") == "python -m experiments.latents --checkpoint=DIR --seed=1"
        and base_example("verify") == "python -m experiments.verify"
    )
    found = {c for _, c in static_examples()}
    assert f"{PREFIX}ablation --seeds=5" in found and f"{PREFIX}ablation --rows=Minsound,proprioception" in found


# ---------------------------------------------------------------- the driver: this file run as a script


class Reached(BaseException):
    """An example reached `BOUNDARIES`: its checks passed. A BaseException, so that no `except
    Exception` of a command takes it for a failure of its own."""


def _patch_boundaries() -> None:
    """Every reference, in every loaded module, to a `BOUNDARIES` function or a benchmark
    function, replaced by one that raises `Reached`; modules imported later bind the replacement."""
    import importlib

    targets = {}
    for dotted, work in BOUNDARIES.items():
        module, name = dotted.rsplit(".", 1)
        targets[id(getattr(importlib.import_module(module), name))] = (dotted, work)
    for mod in list(sys.modules.values()):
        name = getattr(mod, "__name__", "")
        if name.startswith(("fabricjax.bench", "fabricjax.timing", "fabricjax.importers", "acquisition")):
            for attr, value in list(vars(mod).items()):
                if attr.startswith(BENCHMARK_PREFIX) and callable(value) and getattr(value, "__module__", None) == name:
                    targets[id(value)] = (f"{name}.{attr}", "runs a benchmark")

    def stop(dotted: str, work: str):
        def reached(*args, **kwargs):
            raise Reached(f"stopped where it {work} ({dotted})")

        return reached

    stops = {i: stop(*t) for i, t in targets.items()}
    for mod in list(sys.modules.values()):
        for attr, value in list(getattr(mod, "__dict__", {}).items()):
            if id(value) in stops:
                setattr(mod, attr, stops[id(value)])


def _child(argv: list[str], scratch: Path, out: Path, result: Path, help_only: bool) -> None:
    """Run `python -m experiments.<argv[0]> argv[1:]` in this (forked) process up to a boundary;
    its outcome as JSON in `result`, its output in `out`."""
    import runpy

    from absl import flags

    from fabricjax import cli, runtime

    fd = os.open(out, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.environ.update(FABRICJAX_WORKDIR=str(scratch / "workspace"), DISPLAY=os.environ.get("DISPLAY") or ":0")
    redirect = {"workdir": scratch / "workspace", "results": scratch / "results", "doc": scratch / "simulator.md"}
    (scratch / "simulator.md").write_text((REPO / "docs" / "simulator.md").read_text())
    parse = cli._parse

    def parse_into_scratch(args):
        if help_only:
            result.write_text(json.dumps({"helps": {f.name: f.help for f in cli.project_flags()}}))
            os._exit(0)
        return parse([*args, *(f"--{name}={path}" for name, path in redirect.items() if name in flags.FLAGS)])

    cli._parse = parse_into_scratch
    runtime.join_processes = lambda **settings: None  # one process stands for the run over several
    module = f"experiments.{argv[0]}"
    sys.argv = [str(REPO / "experiments" / f"{argv[0]}.py"), *argv[1:]]
    outcome = {"passed": False, "outcome": "ran to the end"}
    try:
        runpy.run_module(module, run_name="__main__", alter_sys=True)
        outcome = {"passed": True, "outcome": "ran to the end"}
    except Reached as e:
        outcome = {"passed": True, "outcome": str(e)}
    except SystemExit as e:
        code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
        outcome = {"passed": code == 0, "outcome": f"exit status {code}"}
    except BaseException as e:  # a bug: its traceback goes to the output
        import traceback

        traceback.print_exc()
        outcome = {"passed": False, "outcome": f"{type(e).__name__}: {e}"}
    sys.stdout.flush()
    sys.stderr.flush()
    result.write_text(json.dumps(outcome))
    os._exit(0)


def _fork(argv: list[str], scratch: Path, help_only: bool = False) -> dict:
    """`_child` in a forked process, waited for up to `TIMEOUT_S`: its outcome and output."""
    scratch.mkdir(parents=True)
    out, result = scratch / "output.txt", scratch / "result.json"
    pid = os.fork()
    if pid == 0:
        try:
            os.chdir(scratch)
            _child(argv, scratch, out, result, help_only)
        finally:
            os._exit(1)
    deadline = time.monotonic() + TIMEOUT_S
    while os.waitpid(pid, os.WNOHANG) == (0, 0):
        if time.monotonic() > deadline:
            os.kill(pid, 9)
            os.waitpid(pid, 0)
            return {
                "passed": False,
                "outcome": f"reached no boundary in {TIMEOUT_S} s",
                "output": out.read_text(errors="replace"),
            }
        time.sleep(0.02)
    outcome = json.loads(result.read_text()) if result.exists() else {"passed": False, "outcome": "the process died"}
    return {**outcome, "output": out.read_text(errors="replace") if out.exists() else ""}


def _drive() -> None:
    """Read {"examples": [(where, command)], "scratch": folder} on stdin; add every command's flag
    help examples; print the outcome of each example as one JSON line."""
    jobs = json.loads(sys.stdin.read())
    scratch = Path(jobs["scratch"])
    # the libraries every command imports, once, before forking (no JAX backend starts here)
    import fabricjax.bench.suite  # noqa: F401
    import fabricjax.inference.view  # noqa: F401
    import fabricjax.sim  # noqa: F401
    import fabricjax.store.integrity  # noqa: F401
    import fabricjax.studies.diagnostics.calibrate  # noqa: F401
    import fabricjax.studies.diagnostics.camera_frames  # noqa: F401
    import fabricjax.studies.diagnostics.flow_agreement  # noqa: F401
    import fabricjax.studies.diagnostics.palm  # noqa: F401
    import fabricjax.studies.diagnostics.sweep  # noqa: F401
    import fabricjax.studies.release.reproduce  # noqa: F401
    import fabricjax.studies.diagnostics.variant  # noqa: F401

    _patch_boundaries()
    examples = [tuple(e) for e in jobs["examples"]]
    for command in COMMANDS:
        helps = _fork([command], scratch / "help" / command, help_only=True)
        if "helps" in helps:
            examples += help_examples(command, helps["helps"], base_example(command))
        else:  # its flags could not even be listed: run --help, which reports why
            examples.append((f"{PREFIX}{command} --help", f"{PREFIX}{command} --help"))
    seen: dict[str, dict] = {}
    results = []
    for i, (where, command) in enumerate(examples):
        if command not in seen:
            argv = shlex.split(command.removeprefix(PREFIX))
            seen[command] = _fork(argv, scratch / f"{i:03d}")
        results.append({"where": where, "command": command, **seen[command]})
    print(json.dumps(results))


if __name__ == "__main__":
    sys.path.insert(0, str(REPO))
    _drive()
