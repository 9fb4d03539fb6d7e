"""The results of a --data_dir run (issue 26) fit the data: "recorded data", rows compared with
each other, and nothing of the paper's numbers, its claims checklist or the simulator. The
documents are built by hand (no training)."""

import json
import re

import numpy as np
import pytest

from fabricjax.errors import UserError
from fabricjax.reporting import plots
from fabricjax.sequences import data
from fabricjax.studies.machinery import documents
from fabricjax.studies.diagnostics import cost
from fabricjax.studies.paper import bandwidth, latents, noise, properties
from fabricjax.studies.release import reproduce_report

MACHINE = {
    "cpu": "test cpu",
    "vector_units": [],
    "cores": 2,
    "jax": "0",
    "jax_backend": "cpu",
    "devices": [0],
    "platform": "test platform",
    "python": "3",
}
DATASET = {
    "folder": "rig_archives",
    "source": "recorded",
    "generate_s": 0.0,
    "load_s": 3.0,
    "sequences": {"train": 90, "val": 45, "test": 40},
    "trials": {"train": 6, "val": 3, "test": 3},
    "classes": ["cotton canvas", "felt", "oak"],
    "names": {
        "internal": "vibration",
        "proprio": "joints arm_0–arm_6 (angle, velocity, torque)",
        "image": "camera image",
    },
}
PAPER_SENSORS = (
    "minsound",
    "palm mic",
    "proprioception",
    "minsight",
)  # never on recorded data: the data's names instead
ARM = "joints arm_0–arm_6 (angle, velocity, torque)"


def _doc(study, rows, **fields):
    return {
        "study": study,
        "command": "test",
        "preset": "smoke",
        "seeds": [0, 1],
        "machine": MACHINE,
        "dataset": DATASET,
        "train_s": 5.0,
        "rows": [{**r, "seeds": [0, 1]} for r in rows],
        "findings": [],
        "figures": [],
        **fields,
    }


MAJORITY = {"label": 2, "accuracy": 40.0, "known": 40}  # a split's majority class, as `findings.majority` gives it
FINE = [None, None]  # no seed collapsed


def _bandwidth_doc():
    return _doc(
        "bandwidth",
        [
            {
                "name": f"{k:g}",
                "bandwidth_khz": k,
                "psd_bins": 512,
                "wall_s": 1.0,
                "collapsed": {"val": FINE, "test": FINE},
                "accuracy": {"val": {"fabric": [v, v]}, "test": {"fabric": [t, t]}},
            }
            for k, v, t in ((0.55, 0.8, 0.7), (1.1, 0.9, 0.9))
        ],
        modalities=["internal"],
        microphone="vibration",
        majority={"val": MAJORITY, "test": MAJORITY},
    )


def _noise_doc():
    w = {"p_value": 0.5, "min_attainable_p": 0.5, "method": "exact", "describe": "p = 0.5 (exact)"}
    return _doc(
        "noise",
        [
            {
                "name": "internal",
                "modalities": ["internal"],
                "against": None,
                "wilcoxon": None,
                "wall_s": 1.0,
                "accuracy": {"cafe": {"fabric": [0.6, 0.6]}, "test": {"fabric": [0.9, 0.9]}},
                "collapsed": {"cafe": FINE, "test": FINE},
            },
            {
                "name": "internal+proprio",
                "modalities": ["internal", "proprio"],
                "against": "internal",
                "wall_s": 2.0,
                "wilcoxon": {"per_seed": w, "per_sample": w},
                "accuracy": {"cafe": {"fabric": [0.8, 0.8]}, "test": {"fabric": [1.0, 1.0]}},
                "collapsed": {"cafe": FINE, "test": FINE},
            },
        ],
        majority={"cafe": MAJORITY, "test": MAJORITY},
    )


def _properties_doc():
    acc = lambda a: {s: {p: [a, a] for p in properties.PROPERTIES} for s in properties.SPLITS}  # noqa: E731
    return _doc(
        "properties",
        [
            {
                "name": r.name,
                "modalities": list(r.modalities),
                "checkpoint": f"ckpt/{r.name}",
                "wall_s": 1.0,
                "accuracy": acc(a),
                "collapsed": {s: dict.fromkeys(properties.PROPERTIES, FINE) for s in properties.SPLITS},
            }
            for r, a in zip(properties.ROWS, (0.5, 0.75))
        ],
        chance={p: 100.0 / 3 for p in properties.PROPERTIES},
        majority={s: dict.fromkeys(properties.PROPERTIES, MAJORITY) for s in properties.SPLITS},
        fabrics={"test": [0, 1, 2], "holdout": []},
    )


@pytest.mark.parametrize(
    "study, doc, best_gap, other_gap",
    [
        (
            bandwidth,
            _bandwidth_doc(),
            "| 1.1 | 512 | 90.00 ± 0.00 | 40.00 (class 2) | 90.00 ± 0.00 | 40.00 (class 2) | +0.00 |",
            "| 0.55 | 512 | 80.00 ± 0.00 | 40.00 (class 2) | 70.00 ± 0.00 | 40.00 (class 2) | -20.00 |",
        ),
        (
            noise,
            _noise_doc(),
            f"| vibration + {ARM} | 80.00 ± 0.00 | 40.00 (class 2) | +0.00 |",
            "| vibration | 60.00 ± 0.00 | 40.00 (class 2) | -20.00 |",
        ),
        (properties, _properties_doc(), "75.00 ± 0.00 / +0.00", "50.00 ± 0.00 / -25.00"),
    ],
)
def test_recorded_results_compare_rows_not_the_paper(study, doc, best_gap, other_gap):
    md = study.markdown(doc)
    assert md.startswith("# ") and md.splitlines()[0].endswith("on recorded data")
    assert "recorded data `rig_archives` (3 classes, chance 33.3 %)" in md and "(recorded data, read as it is)" in md
    assert documents.RECORDED_NOTE in md and best_gap in md and other_gap in md
    assert "paper" not in md.lower() and "simulat" not in md.lower() and "checklist" not in md.lower()
    prose = re.sub(r"`[^`]*`", "", md).lower()  # paths (a checkpoint's folder is named by its --rows name) aside
    assert not [w for w in PAPER_SENSORS if w in prose]  # the rig's streams, not the hand's sensors


def test_recorded_results_name_rows_by_the_datas_streams():
    noise_md, properties_md = noise.markdown(_noise_doc()), properties.markdown(_properties_doc())
    assert f"- vibration + {ARM} vs vibration: p = 0.5 (exact)" in noise_md
    assert (
        f"holdout fabrics: vibration + {ARM} [%]" in properties_md
        and f"| vibration + {ARM} | 1.0 | `ckpt/internal+proprio` |" in properties_md
    )
    assert (
        f"| training fabrics: vibration + {ARM} + camera image [%] (recorded data / row − best row [pp]) |"
        in properties_md
    )
    simulated = {**_noise_doc(), "dataset": {**DATASET, "source": "simulated"}}
    assert (
        documents.stream_names(simulated) == {}
        and noise.display_name("internal+proprio") == "Minsound + proprioception"
    )


def test_recorded_plots_have_no_paper_marks(tmp_path, monkeypatch):
    titles = []
    save, save_bars = plots._save, plots.plot_seed_bars
    monkeypatch.setattr(plots, "_save", lambda fig, path: titles.append(fig.axes[0].get_title()) or save(fig, path))
    assert bandwidth.plot(tmp_path / "bw.png", _bandwidth_doc()["rows"], "vibration").read_bytes()[:4] == b"\x89PNG"
    assert titles == ["vibration accuracy against PSD bandwidth"]  # the rig's microphone, not Minsound
    ticks = []
    monkeypatch.setattr(
        plots,
        "plot_seed_bars",
        lambda path, groups, series, title: ticks.extend(groups) or save_bars(path, groups, series, title),
    )
    assert noise.plot(tmp_path / "noise.png", _noise_doc()["rows"], DATASET["names"]).read_bytes()[:4] == b"\x89PNG"
    assert ticks == ["vibration", f"vibration\n+ {ARM}"]


def _latents_doc(neighbours):
    return {
        "study": "latents",
        "command": "test",
        "preset": "smoke",
        "checkpoint": "ckpt/minsound",
        "config": {"preset": "smoke", "modalities": ["internal", "proprio"]},
        "checkpoint_seeds": [0, 1],
        "best_val_per_seed": [0.5, 0.6],
        "seed": 1,
        "machine": MACHINE,
        "dataset": DATASET,
        "perplexity": 1.0,
        "points": [{"fabric_id": f, "trial_key": f"t{f}", "sequences": 3, "xy": [f, 0.0]} for f in range(3)],
        "figures": ["latents.png"],
        "holdouts": [2],
        "neighbours": neighbours,
        "findings": [],
    }


def test_recorded_latents_use_the_datas_classes_and_levels_not_the_catalogs():
    # class 0 is a fabric on a rig (the hand's class 0 has no properties); levels only where the manifest gave them
    ss = data.SequenceSet(
        {},
        {
            "fabric": np.array([0, 1, 2, 2]),
            "stretchiness": np.array([-1, -1, -1, -1]),
            "roughness": np.array([1, 3, 1, 1]),
            "thickness": np.array([0, -1, 2, 2]),
        },
        {"fabric_id": np.array([0, 1, 2, 2]), "trial_key": np.array(["a", "b", "c", "c"])},
    )
    fabrics = latents.recorded_fabrics(ss, DATASET["classes"])
    assert fabrics == {
        0: ("cotton canvas", {"stretchiness": None, "roughness": 1, "thickness": 0}),
        1: ("felt", {"stretchiness": None, "roughness": 3, "thickness": None}),
        2: ("oak", {"stretchiness": None, "roughness": 1, "thickness": 2}),
    }
    a = latents.neighbour_agreement(np.array([[0.0], [1.0], [0.9]]), [0, 1, 2], fabrics, holdouts=[2])
    assert [(p["holdout"], p["nearest"], p["agreement"]) for p in a["pairs"]] == [(2, 1, 0.0)]
    assert a["chance"] == pytest.approx(0.25)  # (0.5 with class 0 + 0 with class 1) / 2
    assert a["nearer_cases"] == 1  # roughness only: no training class has thickness 2, stretchiness is not given
    ss.labels["thickness"][3] = 1
    with pytest.raises(
        UserError, match=r"^class 'oak': its trials give thickness levels \[1, 2\]; one class, one level"
    ):
        latents.recorded_fabrics(ss, DATASET["classes"])
    md = latents.markdown(_latents_doc(a))
    assert md.splitlines()[0] == "# Latent space on recorded data" and "recorded data `rig_archives` (3 classes" in md
    assert (
        "3 classes of the test and holdout splits" in md
        and "nearest-neighbour property agreement 0.0 % against chance 25.0 %" in md
    )
    assert "paper" not in md.lower() and "simulat" not in md.lower() and "checklist" not in md.lower()


def _cost_doc():
    point = dict(
        name="att N25",
        group="N x backbone",
        seq_len=25,
        touch_s=25 / 30,
        backbone="attention",
        width=16,
        bandwidth_khz=1.1,
        modalities=["internal"],
        params=1000,
        accuracy_mean=80.0,
        accuracy_sd=1.0,
        majority=MAJORITY,
        collapsed=[None, 2],
        train_s=3.0,
        latency_p50_ms=1.0,
        latency_p99_ms=2.0,
    )
    return {
        "study": "cost",
        "command": "test",
        "preset": "smoke",
        "seeds": [0, 1],
        "machine": MACHINE,
        "dataset": {**DATASET, "shortest_trial_steps": 60, "step_rate": 30.0},
        "base": {
            "backbone": "attention",
            "seq_len": 25,
            "width": 16,
            "bandwidth_khz": 1.1,
            "modalities": ["internal"],
            "n_layers": 1,
            "epochs": 2,
        },
        "paper_point": None,
        "skipped_seq_lens": [],
        "pareto_front": {"touch_s": ["att N25"], "latency_p50_ms": ["att N25"]},
        "total_s": 60.0,
        "points": [point],
        "figures": ["cost_pareto.png"],
    }


def test_recorded_cost_has_no_paper_point_and_steps_at_the_datas_rate():
    md = cost.markdown(_cost_doc())
    assert md.splitlines()[0] == "# What accuracy costs in time on recorded data"
    assert "recorded data `rig_archives` (3 classes, chance 33.3 %)" in md and "shortest trial 60 steps" in md
    assert "touch time: N steps at 30 Hz" in md and documents.RECORDED_NOTE in md and "| 0.83 |" in md
    assert "paper" not in md.lower() and "**" not in md and "simulat" not in md.lower()
    assert "| att N25 | 25 | 0.83 | attention | 16 | 1.1 | vibration |" in md  # the rig's microphone, not the role
    assert "| 80.00 ± 1.00 (collapsed to class 2: 1 of 2 seeds) | 40.00 (class 2) |" in md


def test_the_report_of_recorded_data_names_no_paper(tmp_path):
    doc = _bandwidth_doc()
    (tmp_path / "bandwidth.json").write_text(json.dumps(doc))
    (tmp_path / "bandwidth.md").write_text(bandwidth.markdown(doc))
    manifest = {
        "bandwidth": {
            "key": "k",
            "wall_s": 60.0,
            "command": "python -m experiments.bandwidth --data_dir=rig_archives",
            "finished": "2026-11-25 08:00 UTC",
        }
    }
    text = reproduce_report.write_report(
        tmp_path / "REPORT.md", manifest, "smoke", "d" * 16, "test", 1.0, 1
    ).read_text()
    assert text.splitlines()[0] == "# Report: every study on the smoke preset on recorded data"
    assert "## PSD bandwidth\n" in text and "| [PSD bandwidth](#psd-bandwidth) | 2 | 1.0 min |" in text
    assert documents.RECORDED_NOTE in text and "feature extraction, done once, is in the first study's" in text
    assert "paper" not in text.lower() and "simulat" not in text.lower()
