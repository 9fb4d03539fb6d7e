"""Sequences for training and evaluation: trial archives -> cached features -> split sets.

    sets = load_sequences(config, data_dir, workdir=None)     # dict[str, SequenceSet]

Keys of `sets` are the requested `split_names`, by default all of `SPLITS` = ("train", "val", "test",
"cafe", "holdout"); a split with no trials is a `SequenceSet` of 0 sequences with the same
trailing shapes. Trials of splits not requested are not read (no features are computed for
them). Splits come from the archives' meta (`splits.assign_roles` with the preset's `Splits`),
so a folder of real recordings works the same as a simulated one:

    train, val   lab trials of the training days (val: whole trials, the last of each fabric and
                 day), minus `config.exclude_fabrics`
    test, cafe   test-day lab trials / cafe-condition trials, minus `config.exclude_fabrics` and
                 minus fabrics outside the 21-class label space (new fabrics 21-23)
    holdout      test-day lab trials of the fabrics in `config.exclude_fabrics` (the property
                 experiment sets exclude_fabrics=catalog.PROPERTY_HOLDOUTS); empty otherwise

Sequences start at the first rubbing step: a trial of T steps whose meta says the closing took
C steps (`closing_steps`, written by the recorder and the simulator; 0 when absent) gives
(T - C) // N non-overlapping sequences of N = `config.seq_len` steps, starting at steps
C, C + N, ...; the remainder is dropped, as in the paper. Why: the paper describes each trial as
its 50 rubbing motions "during which measurements from all modalities are continuously
recorded", and the closing (~0.8 s of a fingertip approaching a still fabric) carries no texture:
on the former default preset the first sequence of every trial was mostly closing, and the
transformer scored ~45 % on those against 69 % on rubbing ones. A selected trial with fewer than
N rubbing steps raises `archive.ArchiveError` naming the file.

`SequenceSet` (S sequences; arrays are NumPy, sequences ordered by trial file name, then start):

    inputs   one array per `config.modalities` entry:
      "internal", "external"  float32 (S, N, F)        log10 PSD (welch.py), F = welch.n_bins(
                                                       config.bandwidth_khz): 320 at 15 kHz
      "proprio"               float32 (S, N, 18)       6 joints x (angle, velocity, current)
      "flow"                  float16 (S, N, 2, h, w)  sparse flow, 3x3 patch means (flow.py);
                                                       102x137 for 308x410 frames
      "image"                 uint8   (S, N, H, W, 3)  config.image_size ("down", the paper's 60x80)
                                                       or the archive's size ("full")
    labels   int32 (S,): "fabric" (meta label: 0-20, the 21 classes; in "holdout" up to 23),
             "stretchiness", "roughness", "thickness" (property levels, -1 when unknown, e.g.
             class 0)
    info     (S,): "fabric_id" int32, "day" int32, "trial" int32, "start" int32 (first step),
             "condition" str ("lab"/"cafe"), "trial_key" str (archive file name)

Features are computed once per trial and cached (features/cache.py); only the modalities the
config asks for are computed, and frames are never read for an audio / proprioception config.
"""

from __future__ import annotations

import dataclasses
import os
from typing import Sequence

import numpy as np

from fabricjax import archive, catalog, presets, splits, workspace
from fabricjax.config import Config
from fabricjax.features import cache, welch
from fabricjax.features.extract import feature_for

SPLITS = ("train", "val", "test", "cafe", "holdout")
_SOURCE_FIELD = {"image": "images", "flow": "images", "proprio": "joints"}  # archive field behind a modality


@dataclasses.dataclass(frozen=True)
class SequenceSet:
    inputs: dict[str, np.ndarray]
    labels: dict[str, np.ndarray]
    info: dict[str, np.ndarray]

    def __len__(self) -> int:
        return len(self.info["trial_key"])


def split_of(meta: dict, role: str | None, exclude: tuple[int, ...]) -> str | None:
    """The `SPLITS` entry a trial belongs to under a config's exclusions (None: unused)."""
    fid = meta["fabric_id"]
    if role == "test" and fid in exclude:
        return "holdout"
    if role is None or fid in exclude or (role in ("test", "cafe") and meta["label"] >= catalog.N_CLASSES):
        return None
    return role


def first_step(meta: dict) -> int:
    """The first rubbing step of a trial (0 for archives that do not record the closing)."""
    return int(meta.get("closing_steps", 0))


def n_sequences(entry: archive.IndexEntry, n: int) -> int:
    return max(entry.n_steps - first_step(entry.meta), 0) // n


def _describe(entries: list[archive.IndexEntry], n: int) -> tuple[dict, dict]:
    """Labels and info of every sequence the entries give, in order."""
    rows = [(e.meta, e.file, first_step(e.meta) + k * n) for e in entries for k in range(n_sequences(e, n))]

    def column(get, dtype) -> np.ndarray:
        return np.array([get(*r) for r in rows], dtype)

    labels = {"fabric": column(lambda m, f, s: m["label"], np.int32)}
    for p in archive.PROPERTY_NAMES:
        labels[p] = column(lambda m, f, s: -1 if m["properties"][p] is None else m["properties"][p], np.int32)
    info = {k: column(lambda m, f, s: m[k], np.int32) for k in ("fabric_id", "day", "trial")}
    info["start"] = column(lambda m, f, s: s, np.int32)
    info["condition"] = column(lambda m, f, s: m["condition"], str)
    info["trial_key"] = column(lambda m, f, s: f, str)
    return labels, info


def _sequences(feature: np.ndarray, modality: str, start: int, n_seq: int, n: int, config: Config) -> np.ndarray:
    """A trial's (T, ...) feature -> (n_seq, n, ...) view from step `start`, the remainder dropped."""
    x = _band(feature[start : start + n_seq * n], modality, config)
    return x.reshape(n_seq, n, *x.shape[1:])


def _band(x: np.ndarray, modality: str, config: Config) -> np.ndarray:
    """A feature cut to the config's bandwidth: a PSD's first `welch.n_bins` bins (the last axis);
    other modalities unchanged."""
    return x[..., : welch.n_bins(config.bandwidth_khz)] if modality in archive.MIC_NAMES else x


def narrow(sets: dict[str, SequenceSet], config: Config) -> dict[str, SequenceSet]:
    """Sets loaded for several rows (the union of their modalities, the widest bandwidth) as one
    row's: its modalities only, PSDs cut to its bandwidth. Views, no copies."""
    return {
        k: dataclasses.replace(s, inputs={m: _band(a, m, config) for m, a in s.inputs.items() if m in config.modalities})
        for k, s in sets.items()
    }


def load_sequences(
    config: Config,
    data_dir: str | os.PathLike,
    *,
    workdir: str | os.PathLike | None = None,
    workers: int | None = None,
    progress: bool = True,
    split_names: Sequence[str] = SPLITS,
) -> dict[str, SequenceSet]:
    """The splits `split_names` of the dataset in `data_dir` as sequences of the config's modalities."""
    unknown = [s for s in split_names if s not in SPLITS]
    if unknown:
        raise ValueError(f"unknown splits {unknown}; choose from {SPLITS}")
    wanted = tuple(s for s in SPLITS if s in split_names)
    index = archive.load_index(data_dir, workdir)
    roles = splits.assign_roles([e.meta for e in index.entries], presets.get(config.preset).dataset.splits)
    chosen = [
        (e, s) for e, r in zip(index.entries, roles) if (s := split_of(e.meta, r, config.exclude_fabrics)) in wanted
    ]
    if not chosen:
        raise archive.ArchiveError(index.root, "<folder>", f"no trial belongs to the splits {list(wanted)} (check days and conditions)")
    n = config.seq_len
    for e, _ in chosen:
        if n_sequences(e, n) == 0:
            raise archive.ArchiveError(
                index.path(e), "timestamps",
                f"{e.n_steps} steps of which {e.n_steps - first_step(e.meta)} rubbing, fewer than one sequence of N={n} steps",
            )
    members = {s: [e for e, t in chosen if t == s] for s in wanted}
    features = {m: feature_for(m, config.image_resolution, config.image_size, config.flow_sparsify) for m in config.modalities}
    feats = cache.trial_features(
        index, [e for e, _ in chosen], list(features.values()), workspace.features_dir(workdir),
        workers=workers, progress=progress,
    )
    # Each trial's sequences are copied into arrays preallocated from the index's step counts,
    # so the dataset is held once (not per trial and again concatenated).
    inputs: dict[str, dict[str, np.ndarray]] = {}
    filled = dict.fromkeys(wanted, 0)
    for (e, s), f in zip(chosen, feats, strict=True):  # strict: runs the generator to its end (the bar closes)
        n_seq = n_sequences(e, n)
        trial = {m: _sequences(f[feat.name], m, first_step(e.meta), n_seq, n, config) for m, feat in features.items()}
        if not inputs:
            sizes = {t: sum(n_sequences(x, n) for x in members[t]) for t in wanted}
            inputs = {t: {m: np.empty((sizes[t], *a.shape[1:]), a.dtype) for m, a in trial.items()} for t in wanted}
        for m, a in trial.items():
            if a.shape[1:] != inputs[s][m].shape[1:]:
                raise archive.ArchiveError(
                    index.path(e), _SOURCE_FIELD.get(m, "audio"),
                    f"{m} sequences of shape {a.shape[1:]}, but the dataset's first trial gives {inputs[s][m].shape[1:]}",
                )
            inputs[s][m][filled[s] : filled[s] + n_seq] = a
        filled[s] += n_seq
    return {s: SequenceSet(inputs[s], *_describe(members[s], n)) for s in wanted}
