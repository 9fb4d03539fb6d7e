import gc

import numpy as np
import pytest

from fabricjax import memo
from fabricjax.bench import synthetic
from fabricjax.config import Config
from fabricjax.sequences.inputs import input_statistics
from fabricjax.training import placement, train


@pytest.fixture
def hold_everything(monkeypatch):
    monkeypatch.setattr(memo, "MIN_BYTES", 0)


def test_a_value_is_made_once_per_array_and_key_and_dies_with_the_array(hold_everything):
    made = []
    cache = memo.ByArray(max_entries=2)
    a = np.zeros(4)
    make = lambda tag: lambda: made.append(tag) or tag  # noqa: E731
    assert cache.get(a, "k", make("a,k")) == "a,k"
    assert cache.get(a, "k", make("again")) == "a,k"
    assert cache.get(a, "other", make("a,other")) == "a,other"
    b = a.copy()
    assert cache.get(b, "k", make("b,k")) == "b,k"  # another array, even with the same values
    assert made == ["a,k", "a,other", "b,k"]
    assert len(cache) == 2  # the least recently used, (a, k), went first
    assert cache.get(a, "k", make("a,k made again")) == "a,k made again"
    del a, b
    gc.collect()
    assert len(cache) == 0  # entries die with their arrays


def test_views_of_one_array_share_entries_and_the_byte_budget_holds(hold_everything):
    cache = memo.ByArray(max_entries=10, max_bytes=10, size=lambda value: value)
    a = np.zeros((4, 6))
    assert cache.get(a[:, :3], "k", lambda: 6) == 6
    assert cache.get(a[:, :3], "k", lambda: 7) == 6  # another view object, the same part of `a`
    assert cache.get(a[:, :2], "k", lambda: 5) == 5  # another part: its own entry; 11 bytes > 10
    assert len(cache) == 1 and cache.nbytes == 5


def test_small_arrays_and_device_arrays_are_recomputed():
    made = []
    cache = memo.ByArray(max_entries=4)
    a = np.zeros(4)
    for _ in range(2):
        cache.get(a, "k", lambda: made.append(1))
    assert made == [1, 1] and len(cache) == 0


def test_a_run_on_kept_inputs_equals_a_run_that_places_them_anew(monkeypatch):
    """The rows of a study share their placed inputs and statistics (`placement.KEPT`,
    `inputs._STATISTICS`): a second run on the same arrays reuses them and gives the same
    results as runs that place everything anew."""
    cfg = Config(
        preset="smoke",
        modalities=("image", "proprio"),
        cnn_features=(4,),
        width=16,
        n_layers=1,
        ffn=16,
        seq_len=4,
        epochs=2,
        batch_size=8,
        property_heads=False,
    )
    sets = {
        k: synthetic.data_set(cfg, n, image_hw=(6, 8), seed=s)
        for k, n, s in (("train", 16, 0), ("val", 10, 1), ("test", 12, 2))
    }
    fresh = train.train_and_evaluate(cfg, sets, (0, 1))
    monkeypatch.setattr(memo, "MIN_BYTES", 0)
    first = train.train_and_evaluate(cfg, sets, (0, 1))
    held = len(placement.KEPT)
    kept = train.train_and_evaluate(cfg, sets, (0, 1))
    assert held > 0 and len(placement.KEPT) == held  # nothing new placed: every input was found
    for r in (first, kept):
        np.testing.assert_array_equal(r.metrics["train_loss"], fresh.metrics["train_loss"])
        np.testing.assert_array_equal(
            r.metrics["eval"]["test"]["predictions"]["fabric"], fresh.metrics["eval"]["test"]["predictions"]["fabric"]
        )
    stats = input_statistics(cfg, sets["train"])
    sets["train"]["inputs"]["image"] = sets["train"]["inputs"]["image"].copy()  # another array: its own statistics
    assert all(np.array_equal(stats[k], v) for k, v in input_statistics(cfg, sets["train"]).items())
