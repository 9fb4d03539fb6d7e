"""Training fed from the host (fabricjax/training/feed.py): the device-resident run's bits, from memory or
from memory-mapped files, in blocks of any size."""

import dataclasses

import jax
import numpy as np
import pytest

from fabricjax.bench import synthetic
from fabricjax.config import Config
from fabricjax.training import feed, placement
from fabricjax.training.train import train_and_evaluate

# every kind of input: frames (laid out as rows per block), flow, a PSD, joints; two seeds, each
# with its own shuffle; a remainder batch dropped; evaluation sets that are not whole minibatches
CAMERA = Config(
    preset="smoke",
    modalities=("image", "flow", "internal", "proprio"),
    width=16,
    n_layers=1,
    ffn=32,
    cnn_features=(4, 8),
    audio_hidden=(16, 8),
    proprio_hidden=(16, 8),
    seq_len=6,
    epochs=2,
    batch_size=4,
    warmup_steps=2,
    image_size=(30, 40),
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
    assert placement.reads_from_host(CAMERA, sets(CAMERA, tmp_path)["train"])
    assert not placement.reads_from_host(CAMERA, sets(CAMERA)["train"])
    assert placement.reads_from_host(dataclasses.replace(CAMERA, input_source="disk"), sets(CAMERA)["train"])
    assert not placement.reads_from_host(
        dataclasses.replace(CAMERA, input_source="memory"), sets(CAMERA, tmp_path)["train"]
    )


def test_training_from_memory_mapped_files_in_blocks_is_the_device_resident_run(on_devices, tmp_path, monkeypatch):
    """Read from files, one step per block and one sequence per evaluation block, an epoch per
    call with curves and a checkpoint as studies run it, then resumed from it: the same bits."""
    monkeypatch.setattr(feed, "BLOCK_BYTES", 1)
    on_disk = sets(CAMERA, tmp_path)
    kwargs = dict(seeds=[0, 1], workdir=tmp_path / "checkpoint", log_dir=tmp_path / "curves")
    assert_same_run(on_devices, train_and_evaluate(CAMERA, on_disk, **kwargs))
    assert_same_run(on_devices, train_and_evaluate(CAMERA, on_disk, **kwargs))  # restored, evaluated again


def test_host_memory_is_a_few_blocks_whatever_the_data():
    inputs = sets(CAMERA)["train"]["inputs"]
    one_step = 2 * CAMERA.batch_size * feed.sequence_bytes(inputs)
    assert feed.host_bytes(feed.sequence_bytes(inputs), CAMERA.batch_size, 2) <= 2 * max(feed.BLOCK_BYTES, one_step)
    assert feed.host_bytes(10**9, 32, 5) == 2 * 5 * 32 * 10**9  # one step's minibatches, however large


# The slow test's process may hold this much private memory (RLIMIT_DATA: heap and anonymous
# mappings, not the files it maps): it trains on paper-size flow features of twice that on disk.
LIMIT_GB, FEATURES_GB = 1.25, 2.5
CHILD = """
import resource, sys
limit = int({limit} * 2**30)
resource.setrlimit(resource.RLIMIT_DATA, (limit, limit))
import numpy as np
from fabricjax import runtime
runtime.configure_jax()
from fabricjax.config import Config
from fabricjax.training.train import train_and_evaluate
cfg = Config(
    preset="smoke", modalities=("flow",), width=16, n_layers=1, ffn=32, cnn_features=(4, 8), seq_len={n}, epochs=1,
    batch_size=8,
)
sets = {{
    s: {{
        "inputs": {{"flow": np.load(f"{{sys.argv[1]}}/{{s}}.npy", mmap_mode="r")}},
        "labels": {{"fabric": np.load(f"{{sys.argv[1]}}/{{s}}.labels.npy")}},
    }}
    for s in ("train", "val")
}}
try:
    np.array(sets["train"]["inputs"]["flow"])
    sys.exit("the limit does not bind: the training set fits in memory")
except MemoryError:
    pass
r = train_and_evaluate(cfg, sets, seeds=[0])
print("trained", r.metrics["train_loss"][0, 0], r.metrics["eval"]["val"]["predictions"]["fabric"].shape)
"""


@pytest.mark.slow  # ~2 min: 2.5 GB written, one epoch over it
def test_training_on_features_larger_than_the_memory_limit(tmp_path):
    import subprocess
    import sys

    n, step_shape = 20, (2, 102, 137)  # the paper's pooled flow of 308x410 frames, float16
    per_sequence = n * np.prod(step_shape) * 2
    sizes = {"train": int(FEATURES_GB * 2**30 // per_sequence), "val": 40}
    rng = np.random.default_rng(0)
    for split, count in sizes.items():
        a = np.lib.format.open_memmap(
            tmp_path / f"{split}.npy", mode="w+", dtype=np.float16, shape=(count, n, *step_shape)
        )
        for start in range(0, count, 64):
            a[start : start + 64] = rng.standard_normal((min(64, count - start), n, *step_shape), np.float32)
        a.flush()
        np.save(tmp_path / f"{split}.labels.npy", rng.integers(0, 21, count).astype(np.int32))
        del a
    done = subprocess.run(
        [sys.executable, "-c", CHILD.format(limit=LIMIT_GB, n=n), str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert "trained" in done.stdout and "(1, 40)" in done.stdout
