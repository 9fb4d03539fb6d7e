"""The results of a --data_dir run (issue 26) fit the data: "recorded data", rows compared with
each other, and nothing of the paper's numbers, its claims checklist or the simulator. The
documents are built by hand (no training)."""

import pytest

from fabricjax.studies import bandwidth, documents, noise, properties

MACHINE = {"cpu": "test cpu", "vector_units": [], "cores": 2, "jax": "0", "jax_backend": "cpu", "devices": [0]}
DATASET = {"folder": "rig_archives", "source": "recorded", "generate_s": 0.0, "load_s": 3.0,
           "sequences": {"train": 90, "val": 45, "test": 40}, "trials": {"train": 6, "val": 3, "test": 3},
           "classes": ["cotton canvas", "felt", "oak"]}


def _doc(study, rows, **fields):
    return {"study": study, "command": "test", "preset": "smoke", "seeds": [0, 1], "machine": MACHINE, "dataset": DATASET,
            "train_s": 5.0, "rows": [{**r, "seeds": [0, 1]} for r in rows], "findings": [], **fields}


def _bandwidth_doc():
    return _doc("bandwidth", [
        {"name": f"{k:g}", "bandwidth_khz": k, "psd_bins": 512, "wall_s": 1.0,
         "accuracy": {"val": {"fabric": [v, v]}, "test": {"fabric": [t, t]}}}
        for k, v, t in ((0.55, 0.8, 0.7), (1.1, 0.9, 0.9))
    ], modalities=["internal"])


def _noise_doc():
    w = {"p_value": 0.5, "min_attainable_p": 0.5, "method": "exact", "describe": "p = 0.5 (exact)"}
    return _doc("noise", [
        {"name": "internal", "modalities": ["internal"], "against": None, "wilcoxon": None, "wall_s": 1.0,
         "accuracy": {"cafe": {"fabric": [0.6, 0.6]}, "test": {"fabric": [0.9, 0.9]}}},
        {"name": "internal+proprio", "modalities": ["internal", "proprio"], "against": "internal", "wall_s": 2.0,
         "wilcoxon": {"per_seed": w, "per_sample": w}, "accuracy": {"cafe": {"fabric": [0.8, 0.8]}, "test": {"fabric": [1.0, 1.0]}}},
    ])


def _properties_doc():
    acc = lambda a: {s: {p: [a, a] for p in properties.PROPERTIES} for s in properties.SPLITS}  # noqa: E731
    return _doc("properties", [
        {"name": name, "modalities": list(mods), "checkpoint": f"ckpt/{name}", "wall_s": 1.0, "accuracy": acc(a)}
        for (name, mods), a in zip(properties.ROWS, (0.5, 0.75))
    ], chance={p: 100.0 / 3 for p in properties.PROPERTIES}, majority={s: dict.fromkeys(properties.PROPERTIES, 40.0) for s in properties.SPLITS},
        fabrics={"test": [0, 1, 2], "holdout": []})


@pytest.mark.parametrize("study, doc, best_gap, other_gap", [
    (bandwidth, _bandwidth_doc(), "| 1.1 | 512 | 90.00 ± 0.00 | 90.00 ± 0.00 | +0.00 |", "| 0.55 | 512 | 80.00 ± 0.00 | 70.00 ± 0.00 | -20.00 |"),
    (noise, _noise_doc(), "| Minsound + proprioception | 80.00 ± 0.00 | +0.00 |", "| Minsound | 60.00 ± 0.00 | -20.00 |"),
    (properties, _properties_doc(), "75.00 ± 0.00 / +0.00", "50.00 ± 0.00 / -25.00"),
])
def test_recorded_results_compare_rows_not_the_paper(study, doc, best_gap, other_gap):
    md = study.markdown(doc)
    assert md.startswith("# ") and md.splitlines()[0].endswith("on recorded data")
    assert "recorded data `rig_archives` (3 classes, chance 33.3 %)" in md and "(recorded data, read as it is)" in md
    assert documents.RECORDED_NOTE in md and best_gap in md and other_gap in md
    assert "paper" not in md.lower() and "simulat" not in md.lower() and "checklist" not in md.lower()


def test_recorded_plots_have_no_paper_marks(tmp_path):
    assert bandwidth.plot(tmp_path / "bw.png", _bandwidth_doc()["rows"]).read_bytes()[:4] == b"\x89PNG"
    assert noise.plot(tmp_path / "noise.png", _noise_doc()["rows"]).read_bytes()[:4] == b"\x89PNG"
