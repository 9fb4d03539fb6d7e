"""What a user meets first: --help, a mistake on the command line or in the data folder, JAX's
platform probing (fabricjax/cli.py, experiments/flags.py), and the progress log's ETA."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from fabricjax import cli
from fabricjax.config import Config
from fabricjax.store import workspace
from fabricjax.studies.machinery import ablation_rows, row_training
from fabricjax.studies.machinery.progress import Progress
from fabricjax.studies.paper import ablation

ROOT = Path(__file__).parents[1]


def command(*args, env=None):
    """`python -m experiments.ablation ARGS` as a user runs it: JAX_PLATFORMS unset."""
    env = {k: v for k, v in {**os.environ, **(env or {})}.items() if k != "JAX_PLATFORMS"}
    return subprocess.run(
        [sys.executable, "-m", "experiments.ablation", *args],
        env=env,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_help_lists_the_project_flags_and_exits_0():
    out = command("--help")
    assert out.returncode == 0, out.stderr
    for flag in ("--seeds", "--rows", "--preset", "--set", "--data_dir", "--results", "--workdir", "--cpu_devices"):
        assert flag in out.stdout, flag
    assert "(default: '5')" in out.stdout  # the study's seed count
    assert all(r.name in out.stdout for r in ablation_rows.PAPER_ROWS)  # --rows names the rows
    assert "--logtostderr" not in out.stdout and "--only_check_args" not in out.stdout and "--jax_" not in out.stdout
    assert "libtpu" not in out.stdout + out.stderr


@pytest.mark.parametrize("module", ["experiments.reproduce", "experiments.latents", "experiments.bench"])
def test_help_names_the_command_as_typed_and_no_flag_it_lacks(module):
    """The flags are headed by `python -m <module>`, not by the file's path on this machine, and every
    --flag its text names (the docstring's examples, the flags' help) is one of the command's."""
    out = subprocess.run(
        [sys.executable, "-m", module, "--help"], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    assert f"\npython -m {module}:\n" in out.stdout and str(ROOT.resolve()) not in out.stdout
    defined = set(re.findall(r"^ +--(?:\[no\])?(\w+):", out.stdout, re.M))
    named = set(re.findall(r"--(?:\[no\])?(\w+)", out.stdout)) - {"helpfull"}
    assert "workdir" in defined and named <= defined, sorted(named - defined)


@pytest.mark.parametrize(
    "module",
    ["experiments.psds", "experiments.stream", "experiments.latents", "experiments.probe", "experiments.decide"],
)
def test_every_command_takes_a_workdir(module):
    out = subprocess.run(
        [sys.executable, "-m", module, "--help"], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0 and "--workdir" in out.stdout, out.stderr


def damaged_folder(tmp_path):
    folder = tmp_path / "damaged"
    folder.mkdir()
    (folder / "fabric04_day1_trial00_lab.npz").write_bytes(os.urandom(3000))
    return folder


USER_ERRORS = {  # flags -> what the one line must say
    "no_seeds": (["--seeds=0"], r"flag --seeds=0: 0 is not a positive integer"),
    "unknown_row": (
        ["--rows=foo"],
        r"unknown rows \['foo'\]; choose a row's name or its label, in any case, or a group \(all, paper, ours\): "
        r"image \(Minsight image\), ",
    ),
    "empty_data_dir": (["--data_dir={tmp}/empty"], r"empty: field '<folder>': the folder holds no trial archives"),
    "missing_data_dir": (["--data_dir={tmp}/nope"], r"nope: field '<folder>': dataset folder does not exist"),
    "bad_override_value": (
        ["--set=backbone=lstm"],
        r"--set: backbone must be one of \('attention', 'tcn'\), got 'lstm'",
    ),
    "no_epochs": (["--set=epochs=0"], r"--set: epochs must be at least 1, got 0"),
    "no_batch": (["--set=batch_size=0"], r"--set: batch_size must be at least 1, got 0"),
    "damaged_archive": (
        ["--data_dir={tmp}/damaged"],
        r"fabric04_day1_trial00_lab\.npz: field '<file>': not a readable \.npz archive",
    ),
}


@pytest.mark.parametrize("case", list(USER_ERRORS))
def test_a_user_error_is_one_line_with_status_2_and_leaves_no_results_folder(case, tmp_path):
    args, message = USER_ERRORS[case]
    (tmp_path / "empty").mkdir()
    damaged_folder(tmp_path)
    out = command(
        "--preset=smoke",
        f"--workdir={tmp_path}/ws",
        f"--results={tmp_path}/new",
        *[a.format(tmp=tmp_path) for a in args],
    )
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), out.stderr
    assert re.search(message, lines[0]), lines[0]
    assert "pickle" not in lines[0]  # numpy's advice to unpickle a damaged file is not repeated
    assert not (tmp_path / "new").exists()  # the folder is made by the first file written into it


def test_a_bug_keeps_its_traceback_and_debug_shows_a_user_errors():
    code = "import fabricjax.errors\nfrom fabricjax import cli\ndef main(argv):\n    raise {}('boom')\ncli.run(main)"
    env = {k: v for k, v in os.environ.items() if k != "JAX_PLATFORMS"}

    def run(exc, *args):
        return subprocess.run(
            [sys.executable, "-c", code.format(exc), *args],
            env=env,
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=120,
        )

    bug = run("RuntimeError")
    assert bug.returncode == 1 and "Traceback" in bug.stderr and "RuntimeError: boom" in bug.stderr
    not_ours = run("ValueError")  # a ValueError from numpy or JAX is not a user error
    assert not_ours.returncode == 1 and "Traceback" in not_ours.stderr
    user = "fabricjax.errors.UserError"
    assert run(user).stderr == "error: boom\n"
    debug = run(user, "--verbosity=1")
    assert debug.returncode == 1 and "Traceback" in debug.stderr


def test_jax_platforms_is_cpu_only_where_no_accelerator_can_be():
    assert cli.default_platforms({}, []) == "cpu"
    assert cli.default_platforms({}, ["xla_cuda12"]) is None  # a GPU plugin: JAX looks for the GPU
    assert cli.default_platforms({}, ["libtpu"]) is None
    assert cli.default_platforms({"JAX_PLATFORMS": "cuda"}, []) is None  # the user's choice stands
    assert isinstance(cli.accelerator_plugins(), list)


def test_eta_learns_each_kind_of_row_s_time_from_the_rows_done():
    assert [
        row_training.row_kind(Config(modalities=m)) for m in (("internal",), ("image", "internal"), ("flow", "proprio"))
    ] == ["other", "image", "flow"]
    progress = Progress("x", 4, ["image", "other", "other", "image"])
    progress.finish("a", 150.0, "")  # a camera row first: no audio row done yet, so its rate stands in
    assert progress.eta() == pytest.approx(450.0)
    progress.finish("b", 20.0, "")
    assert progress.eta() == pytest.approx(20.0 + 150.0)  # each kind at its own rate: 20 s per audio row, not 150
    sweep = Progress("s", 2, ["other", "other"], work=[2, 4])  # work: epochs
    sweep.finish("c", 10.0, "")
    assert sweep.eta() == pytest.approx(20.0)
    with pytest.raises(ValueError):
        Progress("z", 3, ["other"])


def test_rows_train_grouped_by_camera_in_the_given_order_within_a_group():
    rows = [
        (m, Config(modalities=m))
        for m in (("image",), ("flow",), ("internal",), ("image", "internal"), ("flow", "internal"), ("proprio",))
    ]
    order = row_training.in_training_order(rows, lambda row: row[1])
    assert [m for m, _ in order] == [
        ("image",),
        ("image", "internal"),
        ("flow",),
        ("flow", "internal"),
        ("internal",),
        ("proprio",),
    ]


def test_progress_names_rows_as_the_table_does():
    assert ablation.display_name("tcn:internal+external+proprio") == "TCN: Minsound + palm mic + proprioception"
    assert ablation.display_name("image+internal") == "Minsight image + Minsound"


def test_results_default_to_the_workspace(tmp_path):
    assert workspace.results_dir(None, tmp_path) == tmp_path / "results" and not (tmp_path / "results").exists()
    assert workspace.results_dir(tmp_path / "mine", tmp_path) == tmp_path / "mine"


# A command that saves an orbax checkpoint and logs a line of its own while a progress bar runs.
LOGS = """
import sys
import numpy as np
from absl import logging
from tqdm import tqdm
from fabricjax import cli
from fabricjax.training import checkpoint

def main(argv):
    mngr = checkpoint.manager(sys.argv[1])
    mngr.save(1, args=checkpoint.ocp.args.Composite(state=checkpoint.ocp.args.StandardSave({{"w": np.ones(3)}})))
    mngr.wait_until_finished()
    bar = tqdm(total=2, desc="bar", file=sys.stderr)
    bar.update(1)
    exec(compile("from absl import logging; logging.info('ours')", {ours!r}, "exec"))
    bar.close()

cli.run(main)
"""


@pytest.mark.parametrize("verbosity", [None, "--verbosity=0"])
def test_other_libraries_info_lines_are_off_unless_asked_and_log_lines_never_share_a_bar_s_line(verbosity, tmp_path):
    code = LOGS.format(ours=str(ROOT / "fabricjax" / "a_module.py"))
    args = [sys.executable, "-c", code, str(tmp_path / "ckpt")] + ([verbosity] if verbosity else [])
    out = subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = [segment for line in out.stderr.split("\n") for segment in line.split("\r")]
    ours = [s for s in lines if "] ours" in s]
    assert len(ours) == 1 and ours[0].startswith("I") and "bar" not in ours[0]
    orbax = [s for s in lines if "orbax" in s or "checkpoint_manager" in s]
    assert bool(orbax) == (verbosity is not None), out.stderr[-2000:]
