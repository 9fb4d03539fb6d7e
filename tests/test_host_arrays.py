"""Host arrays made to be placed: CPU devices read them in place, and what training keeps of them."""

import jax
import numpy as np
import pytest
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from fabricjax import host_arrays, memo
from fabricjax.features import images
from fabricjax.training import placement

pytestmark = pytest.mark.skipif(jax.default_backend() != "cpu", reason="placement in place is XLA:CPU's")


def replicated() -> NamedSharding:
    return NamedSharding(Mesh(np.array(jax.devices()), ("batch",)), PartitionSpec())


@pytest.mark.parametrize("shape, dtype", [((5, 7, 3), np.uint8), ((1000, 33), np.float32), ((0, 4), np.int32)])
def test_an_empty_array_is_aligned_contiguous_zeroed_and_writable(shape, dtype):
    a = host_arrays.empty(shape, dtype)
    assert a.shape == shape and a.dtype == dtype and a.flags.c_contiguous and a.flags.writeable
    assert a.ctypes.data % host_arrays.ALIGNMENT == 0
    assert not a.any()
    a[...] = 7
    assert (a == 7).all()


def test_cpu_devices_read_an_aligned_array_in_place_and_copy_a_misaligned_one():
    aligned = host_arrays.empty((256, 64), np.float32)
    aligned[:] = np.arange(64)
    placed = jax.device_put(aligned, replicated())
    assert host_arrays.placed_in_place(placed, aligned)
    np.testing.assert_array_equal(np.asarray(placed), aligned)
    raw = np.zeros(256 * 64 * 4 + 64, np.uint8)
    start = (-raw.ctypes.data % 64) + 16  # 16 bytes past the boundary, like NumPy's own large arrays
    misaligned = raw[start : start + 256 * 64 * 4].view(np.float32).reshape(256, 64)
    assert not host_arrays.placed_in_place(jax.device_put(misaligned, replicated()), misaligned)


def test_padded_sets_are_aligned_copies_with_the_fill_appended():
    a = np.arange(5 * 3, dtype=np.float32).reshape(5, 3)
    p = host_arrays.padded(a, host_arrays.whole_minibatches(5, 4), -1)
    np.testing.assert_array_equal(p, np.concatenate([a, np.full((3, 3), -1, np.float32)]))
    assert p.ctypes.data % host_arrays.ALIGNMENT == 0
    assert (
        host_arrays.padded(a, host_arrays.whole_minibatches(5, 5), -1) is a
    )  # whole minibatches already: the set itself


def test_pixel_rows_of_a_padded_set_are_the_padded_frames_rows():
    frames = np.random.default_rng(0).integers(0, 256, (5, 4, 3, 2, 3), np.uint8)
    rows = images.to_rows(frames, 8)
    np.testing.assert_array_equal(rows, images.to_rows(host_arrays.padded(frames, 8, 0)))
    assert rows.shape == (8, 6, 3, 4) and not rows[5:].any()
    with pytest.raises(ValueError, match="at most that long"):
        images.to_rows(frames, 4)


def test_training_keeps_placed_copies_but_not_an_array_placed_in_place(monkeypatch):
    """An input placed without a copy costs nothing to place again, and keeping it would keep its
    data set alive (`placement.place_input`); a padded copy or pixel rows are kept for the next row."""
    monkeypatch.setattr(memo, "MIN_BYTES", 0)
    monkeypatch.setattr(placement, "KEPT", memo.ByArray(max_entries=12, size=placement.KEPT.size))
    psd = host_arrays.empty((6, 4, 10), np.float32)
    psd[:] = 1.5
    frames = host_arrays.empty((6, 4, 3, 5, 3), np.uint8)
    name, placed = placement.place_input(psd, "internal", None, replicated())
    assert name == "internal" and host_arrays.placed_in_place(placed, psd) and len(placement.KEPT) == 0
    placement.place_input(psd, "internal", 4, replicated())  # padded to 8 sequences: a copy, kept
    assert len(placement.KEPT) == 1
    name, rows = placement.place_input(frames, "image", None, replicated())
    assert name == "image_rows" and rows.shape == (6, 15, 3, 4) and len(placement.KEPT) == 2
    assert placement.place_input(frames, "image", None, replicated())[1] is rows  # found, not made again
