import dataclasses
import os
import zipfile

import numpy as np
import pytest

from fabricjax.config import Config
from fabricjax.features import images, welch
from fabricjax.sequences import data
from fabricjax.store import archive, dataset_index
from tests.helpers import tiny_archive, tiny_dataset

# fabric 4 and class 0: two trials on each training day, one test trial, one cafe trial;
# fabric 1 (a property holdout) the same; fabric 21 (new) a test trial only.
TRIALS = (
    [(fid, day, t, "lab") for fid in (0, 4, 1) for day in (1, 2) for t in (0, 1)]
    + [(fid, 3, 0, "lab") for fid in (0, 4, 1, 21)]
    + [(fid, 4, 0, "cafe") for fid in (0, 4, 1)]
)
LENGTHS = {(4, 1, 0, "lab"): 61, (4, 3, 0, "lab"): 20, (0, 2, 1, "lab"): 39}
N = 20


def _config(**kw):
    return Config(preset="smoke", seq_len=N, **{"modalities": ("internal", "proprio"), **kw})


@pytest.fixture
def dataset(tmp_path):
    return tiny_dataset(tmp_path / "ds", TRIALS, n_steps=LENGTHS)


@pytest.fixture
def reads(monkeypatch):
    """Records every archive read: (file name, images flag)."""
    calls = []
    real = archive.read_archive

    def counting(path, *, images=True):
        calls.append((os.path.basename(path), images))
        return real(path, images=images)

    monkeypatch.setattr(archive, "read_archive", counting)
    return calls


def test_sequences_cover_each_trial_without_overlap(dataset, tmp_path):
    sets = data.load_sequences(_config(), dataset, workdir=tmp_path / "ws", progress=False)
    assert set(sets) == set(data.SPLITS)
    index = dataset_index.load_index(dataset)
    for s in sets.values():
        for entry in index.entries:
            mine = s.info["trial_key"] == entry.file
            if mine.any():  # T // N sequences at steps 0, N, 2N, ...; the remainder dropped
                assert list(s.info["start"][mine]) == list(range(0, entry.n_steps // N * N, N))
                joints = archive.read_archive(index.path(entry)).joints
                np.testing.assert_array_equal(s.inputs["proprio"][mine], joints[: mine.sum() * N].reshape(-1, N, 18))
    train = sets["train"]
    assert train.inputs["internal"].shape == (len(train), N, 320) and train.inputs["internal"].dtype == np.float32
    assert train.inputs["proprio"].dtype == np.float32
    per_trial = {k: (train.info["trial_key"] == k).sum() for k in set(train.info["trial_key"])}
    assert per_trial["fabric04_day1_trial00_lab.npz"] == 3  # 61 steps
    assert sets["test"].info["trial_key"].tolist().count("fabric04_day3_trial00_lab.npz") == 1  # exactly N


def test_splits_labels_and_holdout(dataset, tmp_path):
    sets = data.load_sequences(_config(exclude_fabrics=(1,)), dataset, workdir=tmp_path / "ws", progress=False)
    trials = {s: set(v.info["trial_key"]) for s, v in sets.items()}
    assert trials["val"] == {f"fabric{f:02d}_day{d}_trial01_lab.npz" for f in (0, 4) for d in (1, 2)}
    assert all(set(v.info["fabric_id"]) <= {0, 4} for s, v in sets.items() if s != "holdout")
    assert trials["holdout"] == {"fabric01_day3_trial00_lab.npz"}  # 21 has no label in 21 classes
    assert set(sets["cafe"].info["condition"]) == {"cafe"} and set(sets["test"].info["day"]) == {3}
    assert not set().union(*(trials[s] for s in ("train", "val"))) & trials["test"]
    zero = sets["train"].labels["roughness"][sets["train"].info["fabric_id"] == 0]
    assert zero.size and np.all(zero == -1)  # class 0 has no properties
    assert np.all(sets["train"].labels["fabric"] == sets["train"].info["fabric_id"])
    assert all(v.dtype == np.int32 for v in sets["train"].labels.values())
    plain = data.load_sequences(_config(), dataset, workdir=tmp_path / "ws", progress=False)
    assert len(plain["holdout"]) == 0 and plain["holdout"].inputs["internal"].shape == (0, N, 320)
    assert 1 in set(plain["train"].info["fabric_id"]) and 21 not in set(plain["test"].info["fabric_id"])


def test_second_load_does_no_feature_work(dataset, tmp_path, reads):
    ws = tmp_path / "ws"
    first = data.load_sequences(_config(), dataset, workdir=ws, progress=False, workers=1)
    assert reads and all(images is False for _, images in reads)  # audio + proprio never reads frames
    reads.clear()
    second = data.load_sequences(_config(bandwidth_khz=2.5), dataset, workdir=ws, progress=False, workers=1)
    assert reads == []  # the bandwidth only truncates cached spectra
    np.testing.assert_array_equal(second["train"].inputs["internal"], first["train"].inputs["internal"][..., :54])


def test_cache_invalidation(dataset, tmp_path, reads, monkeypatch):
    ws = tmp_path / "ws"
    before = data.load_sequences(_config(), dataset, workdir=ws, progress=False, workers=1)
    reads.clear()
    # rewriting one archive recomputes that trial only
    a = tiny_archive(45, fabric_id=0, day=1, trial=0, seed=99)
    archive.write_archive(dataset / "fabric00_day1_trial00_lab.npz", a)
    after = data.load_sequences(_config(), dataset, workdir=ws, progress=False, workers=1)
    assert reads == [("fabric00_day1_trial00_lab.npz", False)]
    mine = after["train"].info["trial_key"] == "fabric00_day1_trial00_lab.npz"
    assert not np.array_equal(after["train"].inputs["proprio"][mine], before["train"].inputs["proprio"][mine])
    np.testing.assert_array_equal(after["train"].inputs["proprio"][mine], a.joints[:40].reshape(2, N, 18))
    # a changed feature parameter recomputes that feature everywhere
    reads.clear()
    monkeypatch.setattr(welch, "LOG_FLOOR", 1e-12)
    data.load_sequences(_config(), dataset, workdir=ws, progress=False, workers=1)
    assert len(reads) == len(dataset_index.load_index(dataset).entries) - 1  # all but fabric 21


def test_image_and_flow_features(tmp_path, reads):
    trials = [(4, 1, 0, "lab"), (4, 1, 1, "lab"), (4, 3, 0, "lab")]
    ds = tiny_dataset(tmp_path / "ds", trials, n_steps=41, images=(20, 26))
    cfg = _config(modalities=("image", "flow"), image_reference="training_mean")
    sets = data.load_sequences(cfg, ds, workdir=tmp_path / "ws", progress=False, workers=1)
    assert sets["train"].inputs["image"].shape == (2, N, 60, 80, 3) and sets["train"].inputs["image"].dtype == np.uint8
    assert sets["train"].inputs["flow"].shape == (2, N, 2, 6, 9) and sets["train"].inputs["flow"].dtype == np.float16
    assert not sets["train"].inputs["flow"][0, 0].any()  # step 0 of a trial has no flow
    full_cfg = dataclasses.replace(cfg, image_resolution="full")
    full = data.load_sequences(full_cfg, ds, workdir=tmp_path / "ws", progress=False, workers=1)
    trial = archive.read_archive(ds / "fabric04_day3_trial00_lab.npz")
    np.testing.assert_array_equal(full["test"].inputs["image"][1], trial.images[N : 2 * N])
    # read against the session's reference (the default), at either resolution: int16 differences
    for resolution, shrink in (("down", lambda x: images.downsample(x, (60, 80))), ("full", lambda x: x)):
        session = data.load_sequences(
            dataclasses.replace(cfg, image_reference="session", image_resolution=resolution),
            ds,
            workdir=tmp_path / "ws",
            progress=False,
            workers=1,
        )["test"].inputs["image"][1]
        f32 = lambda x: shrink(x.astype(np.float32))  # noqa: E731
        want = np.rint((f32(trial.images[N : 2 * N]) - f32(trial.reference).mean(0)) * images.DIFFERENCE_SCALE)
        assert session.dtype == np.int16
        np.testing.assert_array_equal(session, want.astype(np.int16))


def test_missing_images_is_a_clear_error(tmp_path):
    ds = tiny_dataset(tmp_path / "ds", [(4, 1, 0, "lab"), (4, 3, 0, "lab")], images=None)
    with pytest.raises(archive.ArchiveError, match=r"fabric04_day1_trial00_lab\.npz: field 'images'"):
        data.load_sequences(_config(modalities=("flow",)), ds, workdir=tmp_path / "ws", progress=False)


def test_trial_shorter_than_a_sequence_names_the_file(tmp_path):
    ds = tiny_dataset(tmp_path / "ds", [(4, 1, 0, "lab"), (4, 3, 0, "lab")], n_steps={(4, 3, 0, "lab"): 19})
    with pytest.raises(archive.ArchiveError, match=r"fabric04_day3_trial00_lab\.npz: field 'timestamps': 19 steps"):
        data.load_sequences(_config(), ds, workdir=tmp_path / "ws", progress=False)


def test_only_the_requested_splits_are_read(dataset, tmp_path, reads):
    full = data.load_sequences(_config(), dataset, workdir=tmp_path / "ws1", progress=False, workers=1)
    n_read = len(reads)
    sets = data.load_sequences(
        _config(), dataset, workdir=tmp_path / "ws2", progress=False, workers=1, split_names=("test", "train")
    )
    assert list(sets) == ["train", "test"]  # in SPLITS order
    for s in sets:
        np.testing.assert_array_equal(sets[s].inputs["internal"], full[s].inputs["internal"])
    second = [name for name, _ in reads[n_read:]]  # the second load's reads: no cafe or validation trial
    assert second and not any("cafe" in name for name in second)
    assert not any(name in second for name in full["val"].info["trial_key"])
    with pytest.raises(ValueError, match="unknown splits"):
        data.load_sequences(
            _config(), dataset, workdir=tmp_path / "ws3", progress=False, workers=1, split_names=("training",)
        )


def test_sequences_start_at_the_first_rubbing_step(tmp_path):
    """With meta closing_steps = C, a trial of T steps gives (T - C) // N sequences from step C."""
    a = tiny_archive(75, fabric_id=4, day=1, trial=0)
    a = dataclasses.replace(a, meta={**a.meta, "closing_steps": 12})
    folder = tmp_path / "ds"
    archive.write_archive(folder / archive.trial_filename(a.meta), a)
    tiny_dataset(folder, [(4, 1, 1, "lab"), (4, 3, 0, "lab")])  # no closing_steps: from step 0
    sets = data.load_sequences(_config(), folder, workdir=tmp_path / "ws", progress=False, split_names=("train",))
    mine = sets["train"].info["trial_key"] == archive.trial_filename(a.meta)
    assert list(sets["train"].info["start"][mine]) == [12, 32, 52]  # (75 - 12) // 20 = 3
    np.testing.assert_array_equal(sets["train"].inputs["proprio"][mine], a.joints[12:72].reshape(3, N, 18))


def test_feature_process_pool_equals_the_serial_path(dataset, tmp_path):
    """Features computed in 2 worker processes are bit-identical to those computed in-process."""
    cfg = _config(modalities=("internal", "external", "proprio", "flow"))
    serial = data.load_sequences(cfg, dataset, workdir=tmp_path / "serial", progress=False, workers=1)
    pooled = data.load_sequences(cfg, dataset, workdir=tmp_path / "pooled", progress=False, workers=2)
    for split in serial:
        for m in cfg.modalities:
            np.testing.assert_array_equal(serial[split].inputs[m], pooled[split].inputs[m])


def test_progress_bars_reach_their_total(dataset, tmp_path, monkeypatch):
    """Every bar closes at total/total: the sequence loop runs the feature generator to its end."""
    from fabricjax.features import cache

    closed = []

    class Recording(cache.tqdm):
        def close(self):
            closed.append((self.desc.split(" ")[0], self.n, self.total))
            super().close()

    monkeypatch.setattr(cache, "tqdm", Recording)
    data.load_sequences(_config(), dataset, workdir=tmp_path / "ws", progress=True, workers=1)
    assert {name for name, _, _ in closed} == {"features", "sequences"}
    assert all(n == total > 0 for _, n, total in closed), closed


def test_an_archive_error_in_a_feature_worker_reaches_the_caller(tmp_path):
    """A worker process's ArchiveError is re-raised in the parent, naming the file (not a hang)."""
    folder = tiny_dataset(tmp_path / "ds", [(4, 1, 0, "lab"), (4, 1, 1, "lab")], images=None)
    with pytest.raises(archive.ArchiveError, match="fabric04_day1_trial0.*images.*absent"):
        data.load_sequences(_config(modalities=("flow",)), folder, workdir=tmp_path / "ws", progress=False, workers=2)


def test_the_feature_cache_deflates_8_and_16_bit_features_and_stores_float32(tmp_path):
    from fabricjax.features import cache

    rng = np.random.default_rng(0)
    arrays = {
        "frames": rng.integers(0, 8, (50, 6, 8, 3)).astype(np.uint8),
        "flow": np.zeros((50, 2, 4, 5), np.float16),
        "psd": rng.normal(size=(50, 24)).astype(np.float32),
    }
    for name, a in arrays.items():
        path = tmp_path / f"{name}.npz"
        cache.save(path, "fp", a)
        members = {i.filename: i.compress_type for i in zipfile.ZipFile(path).infolist()}
        assert members["data.npy"] == (zipfile.ZIP_STORED if a.dtype == np.float32 else zipfile.ZIP_DEFLATED)
        loaded = cache.load(path, "fp")
        assert loaded.dtype == a.dtype and np.array_equal(loaded, a)
        assert cache.load(path, "another archive version") is None


def test_feature_workers_run_jax_on_the_cpu_even_once_jax_is_imported():
    """A feature worker imports JAX before its initializer runs (unpickling the job imports the
    module); on a GPU machine, JAX then read the platforms already, and every worker claimed the
    GPU's memory. The initializer must put such a JAX on the CPU."""
    import subprocess
    import sys

    code = (
        "import os; os.environ.pop('JAX_PLATFORMS', None)\n"
        "import jax\n"
        "from fabricjax.features import cache\n"
        "cache._one_thread_per_worker()\n"
        "print(jax.config.jax_platforms, jax.default_backend())\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["cpu", "cpu"]


def test_loaded_sequences_are_read_only(dataset, tmp_path):
    """Training keeps what it derives from loaded arrays (`fabricjax.memo`): they must not change in place."""
    sets = data.load_sequences(_config(), dataset, workdir=tmp_path / "ws", progress=False)
    for s in sets.values():
        for a in s.inputs.values():
            with pytest.raises(ValueError, match="read-only"):
                a[...] = 0


def test_sequences_larger_than_memory_are_memory_mapped_files(dataset, tmp_path, reads, monkeypatch):
    """input_source="disk" (and "auto" beyond MEMORY_FRACTION of memory): the same sequences, in
    read-only files a second load reads without touching the archives; the folder is outside the data."""
    cfg = _config(modalities=("internal", "proprio", "flow", "image"))
    in_memory = data.load_sequences(
        dataclasses.replace(cfg, input_source="memory"), dataset, workdir=tmp_path / "ws", progress=False
    )
    monkeypatch.setattr(data, "MEMORY_FRACTION", 1e-12)  # every data set is "larger than memory"
    for source in ("auto", "disk"):
        on_disk = data.load_sequences(
            dataclasses.replace(cfg, input_source=source), dataset, workdir=tmp_path / "ws", progress=False
        )
        for split, s in in_memory.items():
            for m, a in s.inputs.items():
                b = on_disk[split].inputs[m]
                assert isinstance(b, np.memmap) and not b.flags.writeable and str(tmp_path / "ws") in str(b.filename)
                np.testing.assert_array_equal(a, b)
    reads.clear()
    data.load_sequences(dataclasses.replace(cfg, input_source="disk"), dataset, workdir=tmp_path / "ws", progress=False)
    assert reads == []
    assert not list((tmp_path / "ws" / "sequences").glob("*.partial"))
    monkeypatch.setattr(data, "MEMORY_FRACTION", 0.5)  # stored, but it fits: "auto" holds it in memory
    fits = data.load_sequences(cfg, dataset, workdir=tmp_path / "ws", progress=False)
    assert not isinstance(fits["train"].inputs["image"], np.memmap)


def test_sequences_that_do_not_fit_the_disk_are_refused_having_written_nothing(dataset, tmp_path, monkeypatch):
    import shutil

    from fabricjax.errors import UserError

    real = shutil.disk_usage
    monkeypatch.setattr(shutil, "disk_usage", lambda path: real(path)._replace(free=10))
    with pytest.raises(UserError, match=r"need \d+ kB of memory-mapped files, only 0 kB free") as e:
        data.load_sequences(_config(input_source="disk"), dataset, workdir=tmp_path / "ws", progress=False)
    assert "\n" not in str(e.value) and not list((tmp_path / "ws" / "sequences").iterdir())


def test_a_load_stopped_by_an_error_leaves_no_reader_behind_and_cannot_deadlock(dataset, tmp_path, monkeypatch):
    """The hang this guards against: a load whose consumer raised left its feature readers
    working; the garbage collector later finalised it inside code holding the cache's lock, and
    its shutdown waited for readers that waited for that lock. Here every npy header parse runs
    the collector (and is slow, so the first load's readers still have work) while the failed
    load's state sits in a reference cycle that only the collector frees. The failed load must
    leave no thread behind, and the next load must finish."""
    import ast
    import gc
    import threading
    import time

    COLLECTIONS = 4  # a full collection in a big test process takes a while: a few make the case
    cfg = _config()
    workdir = tmp_path / "ws"
    data.load_sequences(cfg, dataset, workdir=workdir, progress=False, workers=1)  # every feature cached
    before = set(threading.enumerate())
    parse = ast.literal_eval

    collections = []

    def collecting_parse(text):  # slow, so the failed load's readers still have work; collecting, at first
        time.sleep(0.01)
        if len(collections) < COLLECTIONS:
            collections.append(1)
            gc.collect()
        return parse(text)

    real_sequences = data._sequences
    calls = []

    def failing_sequences(*args):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("the consumer stops")
        return real_sequences(*args)

    outcome = {}

    def scenario():
        monkeypatch.setattr(ast, "literal_eval", collecting_parse)
        monkeypatch.setattr(data, "_sequences", failing_sequences)
        try:
            data.load_sequences(cfg, dataset, workdir=workdir, progress=False, workers=1)
        except RuntimeError as err:
            cycle = [err]
            cycle.append(cycle)  # the error's frames (and the load's state) now wait for the collector
            outcome["left"] = [t.name for t in set(threading.enumerate()) - before - {threading.current_thread()}]
        del cycle
        collections.clear()  # the next load's first parses run the collector, while those readers may still read
        monkeypatch.setattr(data, "_sequences", real_sequences)
        outcome["sets"] = data.load_sequences(cfg, dataset, workdir=workdir, progress=False, workers=1)

    runner = threading.Thread(target=scenario, daemon=True)
    runner.start()
    runner.join(timeout=90)
    assert not runner.is_alive(), "the load after a failed load deadlocked"
    assert outcome["left"] == [], f"threads left running by the failed load: {outcome['left']}"
    assert set(outcome["sets"]) == set(data.SPLITS)


def test_memory_mapped_sequences_of_another_code_version_are_never_read(dataset, tmp_path, monkeypatch):
    """The stored sequences are keyed by the code that makes them, as the feature cache is: files
    written by another version of `sequences.data` or of the features are made anew, not read."""
    from fabricjax import source

    cfg = _config(input_source="disk")
    first = data.load_sequences(cfg, dataset, workdir=tmp_path / "ws", progress=False, workers=1)
    real = source.fingerprint
    monkeypatch.setattr(source, "fingerprint", lambda roots, *a: "another version " + real(roots, *a))
    second = data.load_sequences(cfg, dataset, workdir=tmp_path / "ws", progress=False, workers=1)
    folders = [p.name for p in (tmp_path / "ws" / "sequences").iterdir()]
    assert len(folders) == 2, folders
    assert first["train"].inputs["internal"].filename != second["train"].inputs["internal"].filename
