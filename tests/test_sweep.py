"""The recipe sweep (experiments.sweep) on the smoke preset: grid parsing, its errors, the points
it trains and the results file it writes."""

import itertools
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fabricjax import sim
from fabricjax.config import Config
from fabricjax.errors import UserError
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import loading
from fabricjax.studies.diagnostics import sweep
from fabricjax.studies.paper import ablation

REPO = Path(__file__).parents[1]
ENV = {**os.environ, "JAX_PLATFORMS": "cpu", "JAX_DISABLE_MOST_OPTIMIZATIONS": "1"}
FIXED = dict(width=16, n_layers=1)  # tiny on top of the smoke preset; the grid sweeps epochs
ROWS = ["internal", "proprio"]


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """The smoke dataset without camera frames (the rows here use none)."""
    root = tmp_path_factory.mktemp("sweep")
    sim.ensure_dataset("smoke", root, streams=("audio", "proprio"), progress=False)
    return root


@pytest.fixture(scope="module")
def swept(workdir, tmp_path_factory):
    """epochs=1,2 on two rows, one seed: the returned document and the folder it was written to.
    Four trainings, each compiled afresh (~80 s of CPU in all): the tests that use it are slow."""
    results = tmp_path_factory.mktemp("sweep_results")
    doc = sweep.run(
        grid={"epochs": (1, 2)},
        n_seeds=1,
        preset="smoke",
        rows=ROWS,
        overrides=FIXED,
        latency_repeats=3,
        where=Location(workdir=workdir, results=results, command="test"),
    )
    return doc, results


def test_grid_values_are_read_like_set_with_semicolons_between_tuples():
    grid = sweep.parse_grid(
        [
            "epochs=1,2",
            "cnn_features=4,8;8,16",
            "learning_rate=1e-3;2e-3",
            "augment_rotation=true,false",
            "audio_hidden=32,16",
        ]
    )
    assert grid == {
        "epochs": (1, 2),
        "cnn_features": ((4, 8), (8, 16)),
        "learning_rate": (1e-3, 2e-3),
        "augment_rotation": (True, False),
        "audio_hidden": ((32, 16),),  # a tuple field without ';' is one value
    }
    assert list(grid) == ["epochs", "cnn_features", "learning_rate", "augment_rotation", "audio_hidden"]
    assert sweep.grid_points({"a": (1, 2), "b": ("x", "y")}) == [
        {"a": 1, "b": "x"},
        {"a": 1, "b": "y"},
        {"a": 2, "b": "x"},
        {"a": 2, "b": "y"},
    ]
    assert (
        sweep.point_name({"cnn_features": (4, 8), "augment_rotation": False})
        == "cnn_features=4,8 augment_rotation=false"
    )


@pytest.mark.parametrize(
    "texts, problem",
    [
        (["epochs"], "expected field=v1,v2"),
        (["=1,2"], "expected field=v1,v2"),
        (["epochs="], "expected field=v1,v2"),
        (["epochs=1,,2"], "empty value"),
        (["cnn_features=4,8;"], "empty value"),
        (["epochs=a,2"], "epochs takes int: 'a' is not an integer"),
        (["nofield=1,2"], "Config has no field 'nofield'"),
        (["epochs=1,1"], "a value is repeated"),
        (["audio_hidden=32,16,8"], "3 values given, 2 expected"),
        (["epochs=1", "epochs=2"], "swept by an earlier --grid"),
    ],
)
def test_a_malformed_grid_is_a_one_line_error_naming_the_flag(texts, problem):
    with pytest.raises(UserError) as e:
        sweep.parse_grid(texts)
    message = str(e.value)
    assert message.startswith(f"--grid={texts[-1]}: ") and problem in message and "\n" not in message


@pytest.mark.parametrize(
    "grid, overrides, problem",
    [
        (
            {"modalities": (("internal",), ("proprio",))},
            {},
            f"the sweep study sets modalities per row itself (every one of its {len(ROWS)} rows); "
            f"choose the ablation's rows with --rows",
        ),
        ({"fusion_norm": ("sequence_minmax", "step_layernorm")}, {}, "sets fusion_norm per row itself"),
        ({"epochs": (1,)}, {"fusion_norm": "step_layernorm"}, "sets fusion_norm per row itself"),
        ({"epochs": (1, 2)}, {"epochs": 3}, "--grid and --set both give epochs"),
        ({"preset": ("smoke",)}, {}, "the preset is not a grid field"),
        ({}, {}, "give at least one field"),
        (
            {"backbone": ("attention", "tcn")},
            {},
            "sets backbone per row itself",
        ),  # a grid over it would turn the TCN row into a transformer
        (
            {"lr_schedule": ("constant", "sawtooth")},
            {},
            "--grid point lr_schedule=sawtooth: lr_schedule must be one of",
        ),
        (
            {"fabric_head": (True, False)},
            {"property_heads": True},
            "--grid point fabric_head=false: the sweep ranks recipes by fabric accuracy",
        ),
    ],
)
def test_a_grid_the_sweep_cannot_run_fails_in_one_line_before_any_data_is_read(grid, overrides, problem, tmp_path):
    with pytest.raises(UserError) as e:
        sweep.run(
            grid=grid,
            preset="smoke",
            rows=ROWS,
            overrides=overrides,
            where=Location(workdir=tmp_path / "nothing", results=tmp_path),
        )
    assert problem in str(e.value) and "\n" not in str(e.value)
    assert not (tmp_path / "nothing").exists() and not list(tmp_path.iterdir())


def test_the_command_reports_a_bad_grid_in_one_line_and_exit_2(tmp_path):
    cmd = [
        sys.executable,
        "-m",
        "experiments.sweep",
        "--preset=smoke",
        "--grid=epochs=1,2",
        "--grid=epochs",
        f"--workdir={tmp_path}",
    ]
    out = subprocess.run(cmd, env=ENV, cwd=REPO, capture_output=True, text=True, timeout=120)
    assert (
        out.returncode == 2
        and out.stderr
        == "error: --grid=epochs: expected field=v1,v2,... e.g. --grid=epochs=2,4; "
        "';' between values of a tuple field, e.g. --grid='cnn_features=4,8;8,16'\n"
    ), out.stderr


def entries_for(point, rows, val_means):
    return [{"point": point, "val_mean": v, "test_mean": 50.0, "train_s": 1.0} for _, v in zip(rows, val_means)]


def test_every_point_trains_the_preset_with_set_and_its_own_fields_on_every_row():
    grid, rows = (
        {"epochs": (1, 2), "cnn_features": ((4, 8), (8, 16))},
        [r for r in ablation.ROWS if r.name in ("image", "tcn:internal+external+proprio")],
    )
    units = sweep.plan("smoke", grid, {"learning_rate": 3e-3}, rows)
    assert [name for name, *_ in units] == [
        f"epochs={e}/cnn_features={c}/{r}"
        for e in (1, 2)
        for c in ("4,8", "8,16")
        for r in ("image", "tcn:internal+external+proprio")
    ]  # point-major, the first field slowest; the name is the unit's log folder
    for _, config, fields, row in units:
        expected = Config.from_preset("smoke", learning_rate=3e-3, **row.settings, **fields)
        assert config == expected and config.fusion_norm == row.settings["fusion_norm"]


def test_the_best_point_is_the_first_argmax_of_the_validation_accuracy_averaged_over_rows():
    points = [{"lr": 1}, {"lr": 2}, {"lr": 3}]
    entries = (
        entries_for("lr=1", "ab", [90, 10]) + entries_for("lr=2", "ab", [60, 60]) + entries_for("lr=3", "ab", [20, 100])
    )
    summary, best = sweep.summarise(points, entries)
    assert [p["val_mean_over_rows"] for p in summary] == [
        50,
        60,
        60,
    ] and best == 1  # not the best single row (lr=3 b, lr=1 a)
    assert summary[1]["train_s"] == 2.0 and summary[1]["rows"] == 2


def test_the_last_epoch_is_each_seeds_last_trained_one():
    stopped_early = [[0.2, 0.5, np.nan], [0.1, 0.3, 0.4]]
    assert sweep.last_epoch(stopped_early).tolist() == [0.5, 0.4]


def test_one_load_serves_only_rows_with_the_same_sequences():
    a, b = Config.from_preset("smoke"), Config.from_preset("smoke", seq_len=10, modalities=("proprio",))
    assert loading.sequence_key(a) == loading.sequence_key(
        Config.from_preset("smoke", width=64, modalities=("proprio",))
    )
    with pytest.raises(ValueError, match="need separate loads"):
        loading.load_for_rows([a, b])


def test_sequence_fields_name_every_config_field_the_data_pipeline_reads():
    """A field that decides the loaded sequences but is missing from SEQUENCE_FIELDS would let one
    load serve sweep points it does not fit."""
    sources = [REPO / "fabricjax" / "sequences" / "data.py", *sorted((REPO / "fabricjax" / "features").glob("*.py"))]
    read = {m for p in sources for m in re.findall(r"\bconfig\.([a-z_]+)\b", p.read_text())} & set(
        Config.__dataclass_fields__
    )
    narrowed = {"modalities", "bandwidth_khz"}  # data.narrow gives each row its own
    assert read and read <= set(loading.SEQUENCE_FIELDS) | narrowed, read - set(loading.SEQUENCE_FIELDS) - narrowed


@pytest.mark.slow
def test_sweep_trains_every_point_on_every_row_and_writes_md_and_json(swept):
    doc, results = swept
    assert json.loads((results / "sweep.json").read_text()) == json.loads(json.dumps(doc))
    assert [(e["point"], e["row"]) for e in doc["entries"]] == list(itertools.product(["epochs=1", "epochs=2"], ROWS))
    for e in doc["entries"]:
        assert len(e["accuracy"]["val"]["fabric"]) == 1 and len(e["accuracy"]["test"]["fabric"]) == 1
        assert e["val_mean"] == pytest.approx(100 * e["accuracy"]["val"]["fabric"][0]) and e["val_sd"] == 0.0
        assert (
            e["train_s"] > 0 and e["latency_p50_ms"] > 0 and e["params"] > 0 and 0 <= e["train_last_epoch_mean"] <= 100
        )
    assert [p["name"] for p in doc["points"]] == ["epochs=1", "epochs=2"] and len(doc["loads"]) == 1
    assert (
        doc["study"] == "sweep"
        and doc["command"] == "test"
        and doc["grid"] == {"epochs": [1, 2]}
        and doc["rows"] == ROWS
    )
    md = (results / "sweep.md").read_text()
    assert "- command: `test`" in md and "machine:" in md
    assert f"**Best point by validation accuracy averaged over the 2 rows: `{doc['best']['name']}`**" in md
    assert (
        sum(line.startswith(("| epochs=", "| **epochs=")) for line in md.splitlines()) == 2 + 4
    )  # the points, then point x row


@pytest.mark.slow
def test_the_best_point_is_the_argmax_of_mean_validation_accuracy(swept):
    doc, _ = swept
    mean_val = {}
    for e in doc["entries"]:
        mean_val.setdefault(e["point"], []).append(100 * np.mean(e["accuracy"]["val"]["fabric"]))
    means = [np.mean(v) for v in mean_val.values()]
    assert doc["best"]["name"] == list(mean_val)[int(np.argmax(means))]
    assert doc["best"]["val_mean_over_rows"] == pytest.approx(max(means))


@pytest.mark.slow
def test_each_point_trains_the_preset_with_its_own_fields(swept, workdir):
    """Each point's config is the preset's with the row's settings and the point's fields, as
    trained on the data (`loading.Dataset.config_for`: the data's classes and microphone window)."""
    doc, _ = swept
    rows = {r.name: r for r in ablation.ROWS}
    for e in doc["entries"]:
        r = rows[e["row"]]
        expected = Config.from_preset(
            "smoke",
            **r.settings,
            **FIXED,
            epochs=e["fields"]["epochs"],
        )
        ds = loading.load_for_rows([expected], workdir=workdir, split_names=loading.TRAIN_VAL_TEST)
        assert Config.from_json(e["config"]) == ds.config_for(expected)


@pytest.mark.slow
def test_the_command_sweeps_a_tuple_field_and_loads_once_per_sequence_length(workdir):
    """--grid with ';' between tuple values, and seq_len in the grid: two loads, each serving two points."""
    cmd = [
        sys.executable,
        "-m",
        "experiments.sweep",
        "--preset=smoke",
        "--grid=seq_len=10,20",
        "--grid=audio_hidden=32,16;16,8",
        "--rows=internal",
        "--seeds=1",
        "--set=epochs=1",
        "--latency_repeats=3",
        f"--workdir={workdir}",
    ]
    out = subprocess.run(cmd, check=True, env=ENV, cwd=REPO, capture_output=True, text=True, timeout=600)
    results = workdir / "results"
    assert out.stdout.strip().splitlines()[-1] == f"wrote {results / 'sweep.json'}, {results / 'sweep.md'}"
    assert "sweep: row 4/4 seq_len=20 audio_hidden=16,8 | Minsound done" in out.stderr and "ETA" in out.stderr
    doc = json.loads((results / "sweep.json").read_text())
    assert doc["command"].startswith("python -m experiments.sweep --preset=smoke --grid=seq_len=10,20")
    assert doc["grid"] == {"seq_len": [10, 20], "audio_hidden": [[32, 16], [16, 8]]}
    assert [e["point"] for e in doc["entries"]] == [
        "seq_len=10 audio_hidden=32,16",
        "seq_len=10 audio_hidden=16,8",
        "seq_len=20 audio_hidden=32,16",
        "seq_len=20 audio_hidden=16,8",
    ]
    assert [(e["config"]["seq_len"], e["config"]["audio_hidden"]) for e in doc["entries"]] == [
        (10, [32, 16]),
        (10, [16, 8]),
        (20, [32, 16]),
        (20, [16, 8]),
    ]
    assert [d["seq_len"] for d in doc["loads"]] == [10, 20] and doc["loads"][0]["sequences"]["train"] > doc["loads"][1][
        "sequences"
    ]["train"]
    assert "sequences loaded 2 times" in (results / "sweep.md").read_text()
