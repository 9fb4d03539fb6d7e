"""The variant comparison: per-row paired differences of two training studies' results files,
and one-line refusals of files that are not a variant of each other."""

import json

import numpy as np
import pytest

from fabricjax.errors import UserError
from fabricjax.store.workspace import Location
from fabricjax.studies.diagnostics import variant


def _row(name, test, val, dtype="float32", wall_s=10.0):
    return {
        "name": name,
        "display_name": name.title(),
        "config": {"preset": "smoke", "compute_dtype": dtype},
        "wall_s": wall_s,
        "accuracy": {"val": {"fabric": val}, "test": {"fabric": test}},
    }


def _doc(rows, study="ablation", seeds=(0, 1, 2)):
    return {
        "study": study,
        "command": "python -m experiments.ablation",
        "code": "commit abc",
        "date": "2026-11-25 10:00 UTC",
        "seeds": list(seeds),
        "preset": "smoke",
        "dataset": {"folder": "ws/datasets/smoke", "source": "simulated", "sequences": {"test": 9}},
        "rows": rows,
    }


def _write(path, doc):
    path.write_text(json.dumps(doc))
    return path


def test_paired_differences_and_their_sd(tmp_path):
    base = _write(
        tmp_path / "a.json",
        _doc([_row("internal", [0.5, 0.6, 0.7], [0.4, 0.4, 0.4]), _row("image", [0.1] * 3, [0.1] * 3)]),
    )
    var = _write(
        tmp_path / "b.json",
        _doc(
            [
                _row("internal", [0.6, 0.6, 0.9], [0.4, 0.5, 0.6], "bfloat16", 8.0),
                _row("image", [0.1] * 3, [0.1] * 3, "bfloat16"),
                _row("flow", [0.2] * 3, [0.2] * 3, "bfloat16"),
            ]
        ),
    )
    doc = variant.run(base, var, where=Location(results=tmp_path / "out"))
    internal, image = doc["rows"]
    d = np.array([0.1, 0.0, 0.2])
    assert internal["test"]["difference"] == pytest.approx(d.mean())
    assert internal["test"]["difference_sd"] == pytest.approx(d.std(ddof=1))
    assert internal["val"]["difference"] == pytest.approx(0.1)
    assert internal["test"]["wilcoxon"]["n_nonzero"] == 2
    assert image["test"]["difference"] == 0 and image["test"]["wilcoxon"]["n_nonzero"] == 0
    assert doc["changes"] == {"compute_dtype": ["float32", "bfloat16"]}
    assert doc["rows_not_compared"] == ["flow"]
    md = (tmp_path / "out" / "variant.md").read_text()
    assert "+10.00 ± 10.00" in md and "`compute_dtype`: 'float32' → 'bfloat16'" in md and "not compared: flow" in md
    assert json.loads((tmp_path / "out" / "variant.json").read_text())["of_study"] == "ablation"


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda d: d.update(study="noise"), r"b.json: field 'study' is 'noise'"),
        (lambda d: d.update(seeds=[0, 1]), r"b.json: field 'seeds'"),
        (lambda d: d["dataset"].update(folder="elsewhere"), r"b.json: field 'dataset.folder'"),
        (lambda d: d["rows"][0].update(name="palm"), r"b.json: field 'rows' shares no row"),
        (
            lambda d: d["rows"][0]["config"].update(compute_dtype="float32"),
            r"b.json: field 'rows' .* nothing is varied",
        ),
        (lambda d: d.pop("rows"), r"b.json: field 'rows' missing"),
    ],
)
def test_files_that_are_not_a_variant_are_refused_in_one_line(tmp_path, change, message):
    base = _write(tmp_path / "a.json", _doc([_row("internal", [0.5] * 3, [0.5] * 3)]))
    other = _doc([_row("internal", [0.6] * 3, [0.5] * 3, "bfloat16")])
    change(other)
    var = _write(tmp_path / "b.json", other)
    with pytest.raises(UserError, match=message):
        variant.compare(base, var, command=None)
    assert not (tmp_path / "out").exists()


def test_missing_and_unreadable_files(tmp_path):
    with pytest.raises(UserError, match=r"nope.json: no such results file"):
        variant.read(tmp_path / "nope.json")
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(UserError, match=r"bad.json: not a readable results JSON"):
        variant.read(tmp_path / "bad.json")
