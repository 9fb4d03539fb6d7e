import json

from fabricjax.reporting import results_files


def test_markdown_table_escapes_and_aligns():
    md = results_files.markdown_table(["row", "acc"], [["a|b", "95.00 ± 1.00"], ["c", 1]])
    lines = md.strip().splitlines()
    assert lines[0] == "| row | acc |" and lines[1] == "|---|---|"
    assert "a\\|b" in lines[2] and lines[3] == "| c | 1 |"


def test_write_json_atomic_and_numpy(tmp_path):
    import numpy as np

    p = results_files.write_json(tmp_path / "r" / "x.json", {"a": np.float32(0.5), "b": np.arange(3), "t": (1, 2)})
    assert json.loads(p.read_text()) == {"a": 0.5, "b": [0, 1, 2], "t": [1, 2]}
    assert [q.name for q in p.parent.iterdir()] == ["x.json"]


def test_machine_description():
    m = results_files.machine()
    assert m["cores"] >= 1 and m["jax_backend"] == "cpu" and m["devices"]
