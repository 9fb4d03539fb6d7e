"""Flags shared by the study commands; every `Config` field is a sweep dimension.

    --seeds --preset --rows --set=field=value (repeatable)   (define_rows, study_command)
    --preset --rows --set=field=value (repeatable)           (rows_study_command: no seeds)
    --workdir --data_dir --results --cpu_devices             (always)
    --distributed --coordinator_address --num_processes --process_id   (always: a run over several processes)

`--preset` names a preset of `fabricjax/presets.py` (its data and training settings); each
`--set` overrides one `Config` field on top, typed by the field (`--set=seq_len=100`,
`--set=compute_dtype=bfloat16`, `--set=image_size=30,40`, `--set=modalities=internal,proprio`
where no row of the command sets its inputs) and checked before anything runs. Results go to
<workspace>/results unless --results says otherwise, so a run leaves the repository clean;
`--results=results` regenerates the tables published in the repository.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from absl import flags

from fabricjax import cli, presets, runtime
from fabricjax.config import Config, parse_override
from fabricjax.errors import UserError
from fabricjax.store import provenance, workspace

if TYPE_CHECKING:
    from fabricjax.studies.machinery.runner import Study

FLAGS = flags.FLAGS

flags.DEFINE_string(
    "workdir", None, "workspace root: datasets, features, checkpoints (default $FABRICJAX_WORKDIR or ./workspace)"
)
flags.DEFINE_string(
    "data_dir",
    None,
    "a folder of real recorded trial archives, only read (its index is kept under the workspace); default: "
    "the simulated dataset of the run's preset (of a command that reads a checkpoint: the checkpoint's)",
)
flags.DEFINE_string(
    "results",
    None,
    "where <study>.md/.json and figures are written (default: <workspace>/results; --results=results regenerates "
    "the tables published in the repository)",
)
flags.DEFINE_integer(
    "cpu_devices",
    None,
    "CPU devices for JAX (default: one per core, so that seeds or minibatch samples train on separate cores; "
    "1, the default of experiments.stream and experiments.cost: a single device whose ops share the cores, "
    "the lowest latency for one sequence)",
)

flags.DEFINE_bool(
    "distributed",
    False,
    "join a run over several processes (hosts), each started with the same command: jax.distributed.initialize() "
    "reads a cluster's environment (SLURM, Open MPI, ...); elsewhere give --coordinator_address, "
    "--num_processes and --process_id",
)
flags.DEFINE_string(
    "coordinator_address", None, "host:port of process 0 of a --distributed run outside a cluster scheduler"
)
flags.DEFINE_integer(
    "num_processes", None, "number of processes of a --distributed run outside a cluster scheduler", lower_bound=1
)
flags.DEFINE_integer(
    "process_id",
    None,
    "this process's index (0..num_processes-1) in a --distributed run outside a cluster scheduler",
    lower_bound=0,
)

PROCESS_FLAGS = ("coordinator_address", "num_processes", "process_id")


def distributed() -> dict[str, Any] | None:
    """`runtime.configure_jax`'s `distributed` from the flags: None for a run in this process
    alone, else the explicit settings given (none under a cluster scheduler). Any of the three
    explicit flags implies --distributed."""
    given = {name: getattr(FLAGS, name) for name in PROCESS_FLAGS if getattr(FLAGS, name) is not None}
    return given if FLAGS.distributed or given else None


def run(main, cpu_devices: int | None = None) -> None:
    """`cli.run(main)` with JAX configured before it starts (`runtime.configure_jax`): its CPU
    devices (--cpu_devices, else `cpu_devices`, else one per core) and XLA's compilation cache
    under the workspace (jax_cache/, so a rerun of a study skips compilation), and with
    --distributed this process joins a run over several processes; at the end, the files the
    command wrote into the results folder are listed."""

    def start(argv):
        folder = results_dir()
        before = _snapshot(folder)
        main(argv)
        written = sorted(p for p, st in _snapshot(folder).items() if before.get(p) != st)
        if written and runtime.is_primary():  # the others write nothing (and would list process 0's temporaries)
            print("wrote " + ", ".join(str(p) for p in written))

    def setup():
        runtime.configure_jax(
            cpu_devices=FLAGS.cpu_devices or cpu_devices or runtime.available_cores(),
            compilation_cache_dir=workspace.compilation_cache_dir(FLAGS.workdir),
            distributed=distributed(),
        )

    cli.run(start, before=setup)


def _snapshot(folder: Path) -> dict[Path, tuple[int, int, int]]:
    """Identity of every file in `folder` (inode, size, mtime): atomic writes change the inode. A
    folder not made yet holds none (its first write makes it)."""
    files = {p: p.stat() for p in folder.iterdir() if p.is_file()} if folder.is_dir() else {}
    return {p: (st.st_ino, st.st_size, st.st_mtime_ns) for p, st in files.items()}


def results_dir() -> Path:
    """--results, else <workspace>/results (`workspace.results_dir`)."""
    return workspace.results_dir(FLAGS.results, FLAGS.workdir)


def define_rows(study: Study, n_seeds: int) -> None:
    """The flags of a command that trains rows of `study`: --seeds (default `n_seeds`), --preset,
    --rows (its rows and groups) and --set."""
    from fabricjax.studies.machinery.rows import ALL_ROWS

    flags.DEFINE_integer(
        "seeds", n_seeds, "number of seeds (0..n-1) trained together (the study's count by default)", lower_bound=1
    )
    define_preset()
    flags.DEFINE_list(
        "rows",
        None,
        f"comma-separated rows, each by its name or by the label the tables print, in any case, or a group of "
        f"rows ({', '.join([ALL_ROWS, *study.groups])}); names: {', '.join(study.row_names)} (default: "
        + (f"the rows {', '.join(study.default_rows)}" if study.default_rows is not None else "every row of the table")
        + ")",
    )
    define_overrides(ROWS_REFUSE)


def study_command(study: Study) -> None:
    """The whole command line of a training study (experiments/ablation.py and its three twins):
    its flags, then `study.run` with them."""
    define_rows(study, study.n_seeds)

    flags.DEFINE_bool(
        "plan",
        False,
        "print what the run needs (disk and time per stage) and stop; with --results also write plan.md there",
    )

    def main(argv):
        del argv
        study.run(**rows_kwargs(), plan_only=FLAGS.plan)

    run(main)


def rows_study_command(study) -> None:
    """The whole command line of a deterministic study over named rows (the probe, the day shift):
    --preset, --rows (from `study.ROWS`) and --set, then `study.run` with them."""
    define_preset()
    flags.DEFINE_list(
        "rows",
        None,
        f"comma-separated rows, each by its name or by the label the tables print, in any case; names: "
        f"{', '.join(r.name for r in study.ROWS)} (default: every row)",
    )
    define_overrides(ROWS_REFUSE)

    def main(argv):
        del argv
        study.run(preset=FLAGS.preset, rows=FLAGS.rows, overrides=overrides(), where=location())

    run(main)


def define_preset() -> None:
    flags.DEFINE_enum(
        "preset", "default", sorted(presets.PRESETS), "dataset and training preset (fabricjax/presets.py)"
    )


ROWS_REFUSE = "a field the command's rows set themselves is refused (choose those with --rows)"


def define_overrides(refused: str | None = None) -> None:
    """--set; `refused` tells which fields the command refuses and what chooses them instead (None:
    it refuses none), so that the help names no flag the command lacks."""
    flags.DEFINE_multi_string(
        "set",
        [],
        "override a Config field on top of the preset, field=value (repeatable), e.g. --set=seq_len=100 "
        "--set=compute_dtype=bfloat16" + (f"; {refused}" if refused else ""),
    )


def overrides() -> dict[str, Any]:
    """--set as {field: typed value}, checked by building the preset's config with them (a bad
    field or value is a one-line error before any data is loaded)."""
    out = dict(parse_override(text) for text in FLAGS.set)
    try:
        Config.from_preset(FLAGS.preset, **out)
    except ValueError as e:
        raise UserError(f"--set: {e}") from None
    return out


def rows_kwargs() -> dict[str, Any]:
    """The keyword arguments of `runner.run_study` (and `sweep.run`) from the parsed flags."""
    return dict(n_seeds=FLAGS.seeds, preset=FLAGS.preset, rows=FLAGS.rows, overrides=overrides(), where=location())


def location() -> workspace.Location:
    """Where data and results live, and the command line (recorded in every results file)."""
    return workspace.Location(
        workdir=FLAGS.workdir, data_dir=FLAGS.data_dir, results=results_dir(), command=provenance.command_line()
    )
