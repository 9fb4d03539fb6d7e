"""Training fed from the host (fabricjax/feed.py): the device-resident run's bits, from memory or
from memory-mapped files, in blocks of any size."""

import dataclasses

import jax
import numpy as np
import pytest

from fabricjax import feed
from fabricjax.bench import synthetic
from fabricjax.config import Config
from fabricjax.train import train_and_evaluate

# every kind of input: frames (laid out as rows per block), flow, a PSD, joints; two seeds, each
# with its own shuffle; a remainder batch dropped; evaluation sets that are not whole minibatches
CAMERA = Config(
    preset="smoke", modalities=("image", "flow", "internal", "proprio"), width=16, n_layers=1, ffn=32, cnn_features=(4, 8),
    audio_hidden=(16, 8), proprio_hidden=(16, 8), seq_len=6, epochs=3, batch_size=4, warmup_steps=2, image_size=(30, 40),
    property_heads=True,
)


def sets(config, memmap_dir=None):
    out = {
        name: synthetic.data_set(config, n, seed=seed, image_hw=(30, 40), flow_hw=(10, 14), psd_bins=8)
        for name, n, seed in (("train", 22, 0), ("val", 7, 1), ("test", 9, 2))
    }
    if memmap_dir is not None:  # the inputs as data.load_sequences leaves data larger than memory
        for name, s in out.items():
            for m, a in s["inputs"].items():
                path = memmap_dir / f"{name}.{m}.npy"
                np.save(path, a)
                s["inputs"][m] = np.load(path, mmap_mode="r")
    return out


def assert_same_run(a, b):
    for x, y in zip(jax.tree.leaves(a.state), jax.tree.leaves(b.state), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    for key in ("train_loss", "val_acc", "best_epoch"):
        np.testing.assert_array_equal(a.metrics[key], b.metrics[key])
    for name in ("val", "test"):
        for head, p in a.metrics["eval"][name]["predictions"].items():
            np.testing.assert_array_equal(p, b.metrics["eval"][name]["predictions"][head])


@pytest.fixture(scope="module")
def on_devices():
    return train_and_evaluate(dataclasses.replace(CAMERA, input_source="memory"), sets(CAMERA), seeds=[0, 1])


def test_memory_mapped_inputs_are_read_from_the_host(tmp_path):
    assert feed.reads_from_host(CAMERA, sets(CAMERA, tmp_path)["train"])
    assert not feed.reads_from_host(CAMERA, sets(CAMERA)["train"])
    assert feed.reads_from_host(dataclasses.replace(CAMERA, input_source="disk"), sets(CAMERA)["train"])
    assert not feed.reads_from_host(dataclasses.replace(CAMERA, input_source="memory"), sets(CAMERA, tmp_path)["train"])


def test_training_from_memory_mapped_files_is_the_device_resident_run(on_devices, tmp_path):
    assert_same_run(on_devices, train_and_evaluate(CAMERA, sets(CAMERA, tmp_path), seeds=[0, 1]))


def test_any_block_size_gives_the_same_bits(on_devices, monkeypatch):
    """One step per block and one sequence per evaluation block: blocks change nothing."""
    monkeypatch.setattr(feed, "BLOCK_BYTES", 1)
    assert_same_run(on_devices, train_and_evaluate(dataclasses.replace(CAMERA, input_source="disk"), sets(CAMERA), seeds=[0, 1]))


def test_host_memory_is_a_few_blocks_whatever_the_data():
    inputs = sets(CAMERA)["train"]["inputs"]
    one_step = 2 * CAMERA.batch_size * feed.sequence_bytes(inputs)
    assert feed.host_bytes(inputs, CAMERA.batch_size, 2) <= 2 * max(feed.BLOCK_BYTES, one_step)
