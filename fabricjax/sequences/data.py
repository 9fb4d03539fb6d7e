"""Sequences for training and evaluation: trial archives -> cached features -> split sets.

    sets = load_sequences(config, data_dir, workdir=None)     # dict[str, SequenceSet]

Keys of `sets` are the requested `split_names`, by default all of `SPLITS` = ("train", "val", "test",
"cafe", "holdout"); a split with no trials is a `SequenceSet` of 0 sequences with the same
trailing shapes. Trials of splits not requested are not read (no features are computed for
them). Splits come from the archives' meta (`splits.assign_roles` with the preset's `Splits`):
the split the user gave a trial at import (`meta.split`), else by day, so a folder of real
recordings works the same as a simulated one:

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
counted from step 0 instead, the first sequence of every trial would be mostly closing, a
sequence without the cue the classifier is meant to read. A selected trial with fewer than N
rubbing steps raises `archive.ArchiveError` naming the file.

What the data holds is checked before any of it is read: every selected trial must carry the
streams the config's modalities need (`archive.Layout.modalities`; else a one-line `UserError`
listing what the data has), the microphones a modality uses must share one rate across trials,
and the classes are the trials' label map (`meta.label_map`, all trials alike) or, without one,
the catalog's 21. A training or validation trial with a label outside the classes is an error;
test and cafe trials outside them (the hand's new fabrics 21-23), trials no split uses (a day the
preset does not know) and a bandwidth above a microphone's Nyquist (capped there) are reported
as warnings, and trials of splits not requested (a study reading train, val and test skips cafe
and holdout) are counted in an info line: never silent.

`SequenceSet` (S sequences; arrays are NumPy, sequences ordered by trial file name, then start):

    inputs   one array per `config.modalities` entry:
      "internal", "external"  float32 (S, N, F)        log10 PSD (welch.py) of the microphone of
                                                       that role over its step window (`window_s`
                                                       at its rate: 2048 samples for the hand),
                                                       F = welch.n_bins(config.
                                                       bandwidth_khz, its rate, window): 320 at
                                                       15 kHz and 48 kHz, all 512 at or above its
                                                       Nyquist
      "proprio"               float32 (S, N, J * F)    joints x fields: the hand's 6 x (angle,
                                                       velocity, current), archive.N_PROPRIO
      "flow"                  float16 (S, N, 2, h, w)  sparse flow, 3x3 patch means (flow.py);
                                                       102x137 for 308x410 frames
      "image"                 uint8   (S, N, H, W, 3)  config.image_size ("down", the paper's 60x80)
                                                       or the archive's size ("full"); int16 frames
                                                       minus their session's reference where
                                                       config.image_reference is "session"
    labels   int32 (S,): "fabric" (meta label: 0..n_classes-1; the hand's 21 classes or the first of them, in
             "holdout" up to 23), "stretchiness", "roughness", "thickness" (property levels, -1
             when unknown, e.g. class 0 or a property the recording does not give)
    info     (S,): "fabric_id" int32 (the catalog fabric, or the class of a label map's trial:
             `archive.fabric_or_class`), "day" int32 (-1: no day), "trial" int32, "start" int32
             (first step), "condition" str ("lab"/"cafe", "" where the recording names none),
             "trial_key" str (archive file name)
    rates    {audio modality: its microphone's sample rate, Hz} (what `narrow` cuts bands by)
    names    {modality: how the data names its stream}: a microphone by its name (the rig file's),
             the joints by theirs and their fields (`stream_names`)
    classes  the class names of the label space, by class (its length is the fabric head's size)
    window_s every microphone's step window in seconds (`step_window_s`): `config.mic_window_s` when
             set, else the one the data declares (a rig file's `steps.mic_window_s`, the same in every
             trial), else the paper's 2048 samples at 48 kHz (`config.PAPER_WINDOW_S`)

Features are computed once per trial and cached (features/cache.py); only the modalities the
config asks for are computed, and frames are never read for an audio / proprioception config.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections import Counter
from typing import Mapping, Sequence

import numpy as np
from absl import logging

from fabricjax import catalog, host_arrays, memo, presets, source
from fabricjax.config import MODALITY_NAMES, PAPER_WINDOW_S, Config
from fabricjax.errors import UserError
from fabricjax.features import cache, welch
from fabricjax.features.extract import features_for, window_of
from fabricjax.sequences.sequence_store import SequenceStore
from fabricjax.store import archive, dataset_index, lock, splits, workspace

SPLITS = archive.SPLITS
# Loaded sequences that would take more than this fraction of the machine's memory are filled into
# memory-mapped files instead (`sequence_store`), and training reads them from the host
# (`fabricjax.training.feed`): the rest is left to the model, the features being computed, the page cache.
MEMORY_FRACTION = 0.5
# the code that turns features into sequences: memory-mapped sequences are keyed by it, so that
# files written by another version of it are never read
SEQUENCE_CODE = (__name__,)
_SOURCE_FIELD = {"image": "images", "flow": "images", "proprio": "joints"}  # archive field behind a modality


@dataclasses.dataclass(frozen=True)
class SequenceSet:
    inputs: dict[str, np.ndarray]
    labels: dict[str, np.ndarray]
    info: dict[str, np.ndarray]
    rates: Mapping[str, int] = dataclasses.field(default_factory=dict)  # absent: the hand's 48 kHz
    names: Mapping[str, str] = dataclasses.field(default_factory=dict)  # absent: the paper's (config.MODALITY_NAMES)
    classes: tuple[str, ...] = tuple(catalog.fabric(k).name for k in range(catalog.N_CLASSES))
    window_s: float = PAPER_WINDOW_S  # the microphones' step window [s] (`step_window_s`)
    dataset: Mapping[str, str] = dataclasses.field(
        default_factory=dict
    )  # `DatasetIndex.identity`; absent: made in memory

    @property
    def n_classes(self) -> int:
        return len(self.classes)

    def __len__(self) -> int:
        return len(self.info["trial_key"])


def split_of(meta: dict, role: str | None, exclude: tuple[int, ...], n_classes: int = catalog.N_CLASSES) -> str | None:
    """The `SPLITS` entry a trial belongs to under a config's exclusions (None: unused)."""
    fid = archive.fabric_or_class(meta)
    if role == "test" and fid in exclude:
        return "holdout"
    if role is None or fid in exclude or (role in ("test", "cafe") and meta["label"] >= n_classes):
        return None
    return role


def classes_of(index: dataset_index.DatasetIndex) -> tuple[str, ...]:
    """The dataset's class names by class: its label map's (every archive must carry the same one;
    names sharing a class are joined by " / "), or for archives without one the catalog's classes
    0 up to the highest the dataset has (all 21 on the hand's full set of fabrics; a dataset of
    fabrics 0-4, such as the smoke preset's, has 5), so that the fabric head has no class the data
    never shows."""
    maps = {json_key(e.meta.get("label_map")): e for e in index.entries}
    if len(maps) > 1:
        a, b = list(maps.values())[:2]
        raise archive.ArchiveError(
            index.path(b), "meta.label_map", f"differs from the label map of {a.file} (one dataset, one label map)"
        )
    named = label_classes(index.entries[0].meta)
    if named is None:
        catalog_classes = SequenceSet.__dataclass_fields__["classes"].default
        highest = max(
            (e.meta["label"] for e in index.entries if e.meta["label"] < len(catalog_classes)),
            default=len(catalog_classes) - 1,
        )
        return catalog_classes[: highest + 1]
    return named


def label_classes(meta: dict) -> tuple[str, ...] | None:
    """The class names of a trial's label map by class (names sharing a class joined by " / "),
    None for a trial without one (the catalog's classes)."""
    label_map = meta.get("label_map")
    if label_map is None:
        return None
    return tuple(" / ".join(sorted(n for n, c in label_map.items() if c == k)) for k in range(archive.n_classes(meta)))


def json_key(x) -> str:
    return repr(sorted(x.items())) if isinstance(x, dict) else repr(x)


def check_streams(
    index: dataset_index.DatasetIndex, entries: Sequence[dataset_index.IndexEntry], modalities: Sequence[str]
) -> dict[str, int]:
    """Before any data is read: every trial carries the streams `modalities` need (else a one-line
    error listing what the data has), and each microphone used has one rate in all trials.
    Returns {audio modality: rate}."""
    rates: dict[str, tuple[int, dataset_index.IndexEntry]] = {}
    for e in entries:
        lay = archive.layout(e.meta)
        lacking = [m for m in modalities if m not in lay.modalities()]
        if lacking:
            names = ", ".join(f"{m} ({MODALITY_NAMES[m]})" for m in lacking)
            raise archive.ArchiveError(
                index.path(e),
                _SOURCE_FIELD.get(lacking[0], "audio"),
                f"absent: the data has no {names} for the modalities {', '.join(modalities)}; it has {lay.describe()} "
                f"(choose rows or modalities it supports: {', '.join(lay.modalities()) or 'none'})",
            )
        for m in modalities:
            k = lay.mic(m)
            if k is None:
                continue
            rate = lay.mics[k].rate
            first = rates.setdefault(m, (rate, e))
            if first[0] != rate:
                raise archive.ArchiveError(
                    index.path(e),
                    "meta.streams.mics",
                    f"the {m} microphone runs at {rate} Hz, but at {first[0]} Hz in {first[1].file} (one "
                    f"rate per microphone in a dataset)",
                )
    return {m: r for m, (r, _) in rates.items()}


def _report_unused(
    entries: Sequence[dataset_index.IndexEntry], roles, chosen_split, n_classes: int, wanted: Sequence[str]
) -> None:
    """Say which trials no split uses, and why (a day no split names, a label outside the classes),
    and how many of the splits the caller does not read there are (a study reading train, val and
    test skips cafe and holdout trials, which would otherwise vanish from a --data_dir run unsaid)."""
    no_role = [e for e, r in zip(entries, roles) if r is None]
    if no_role:
        days = sorted({str(e.meta["day"]) for e in no_role})
        logging.warning(
            "%d trials belong to no split and are not used (days %s: not among the preset's days, and no split "
            "given at import), e.g. %s",
            len(no_role),
            ", ".join(days),
            no_role[0].file,
        )
    outside = [
        e
        for e, r in zip(entries, roles)
        if r in ("test", "cafe") and chosen_split(e, r) is None and e.meta["label"] >= n_classes
    ]
    new = [e for e in outside if "label_map" not in e.meta and e.meta["fabric_id"] in catalog.NEW_FABRICS]
    if new:  # the hand's test day, by design: what they are, not a warning
        logging.info(
            "the test day's new fabrics %s (%d test trial%s) have no training trials: they are the property study's "
            "holdouts, not classes of the fabric classifier",
            ", ".join(map(str, sorted({e.meta["fabric_id"] for e in new}))),
            len(new),
            "s" * (len(new) != 1),
        )
    outside = [e for e in outside if e not in new]
    if outside:
        labels = sorted({e.meta["label"] for e in outside})
        logging.warning(
            "%d %s trials have labels outside the %d classes (%s) and are not evaluated, e.g. %s",
            len(outside),
            "/".join(sorted({r for e, r in zip(entries, roles) if e in outside})),
            n_classes,
            ", ".join(map(str, labels)),
            outside[0].file,
        )
    skipped = Counter(s for e, r in zip(entries, roles) if (s := chosen_split(e, r)) not in (None, *wanted))
    if skipped:
        logging.info(
            "%s are not used by this study (it reads %s)",
            ", ".join(f"{skipped[s]} trials on split {s}" for s in SPLITS if s in skipped),
            ", ".join(wanted),
        )


def _fill(
    index, chosen, members, features, config: Config, rates, store: SequenceStore, features_root, workers, progress
) -> dict[str, dict[str, np.ndarray]]:
    """{split: {modality: (S, N, ...)}}: each trial's sequences of its features (cached, or
    computed first) copied into arrays preallocated from the index's step counts, so the dataset
    is held once (not per trial and again concatenated): in memory where CPU devices can read them
    without a copy (`host_arrays`), or in `store`'s files where they would take more than
    `MEMORY_FRACTION` of memory (or `config.input_source` says "disk"). Read-only."""
    n, wanted = config.seq_len, tuple(members)
    loader = cache.trial_features(
        index,
        [e for e, _ in chosen],
        list(features.values()),
        features_root,
        workers=workers,
        progress=progress,
    )
    with loader as feats:
        inputs: dict[str, dict[str, np.ndarray]] = {}
        filled = dict.fromkeys(wanted, 0)
        for (e, s), f in zip(chosen, feats, strict=True):  # strict: reads to the end (the bar closes)
            n_seq = n_sequences(e, n)
            trial = {
                m: _sequences(f[feat.name], m, first_step(e.meta), n_seq, n, config, rates)
                for m, feat in features.items()
            }
            if not inputs:
                inputs = _allocate(trial, members, n, config, store)
            for m, a in trial.items():
                if a.shape[1:] != inputs[s][m].shape[1:]:
                    raise archive.ArchiveError(
                        index.path(e),
                        _SOURCE_FIELD.get(m, "audio"),
                        f"{m} sequences of shape {a.shape[1:]}, but the dataset's first trial gives "
                        f"{inputs[s][m].shape[1:]}",
                    )
                inputs[s][m][filled[s] : filled[s] + n_seq] = a
            filled[s] += n_seq
    if any(isinstance(a, np.memmap) for d in inputs.values() for a in d.values()):
        return store.finish(inputs)
    for arrays in inputs.values():  # read-only from here: training keeps what it derives (`fabricjax.memo`)
        for a in arrays.values():
            a.flags.writeable = False
    return inputs


def _allocate(
    first: dict[str, np.ndarray], members, n: int, config: Config, store: SequenceStore
) -> dict[str, dict[str, np.ndarray]]:
    """{split: {modality: empty (S, N, ...)}} shaped from the first trial's sequences and the
    index's step counts: in memory, or in `store`'s files past `MEMORY_FRACTION` of memory."""
    shapes = {
        t: {m: ((sum(n_sequences(x, n) for x in members[t]), *a.shape[1:]), a.dtype) for m, a in first.items()}
        for t in members
    }
    total = sum(math.prod(shape) * np.dtype(dtype).itemsize for t in shapes.values() for shape, dtype in t.values())
    on_disk = config.input_source == "disk" or (
        config.input_source == "auto" and total > memo.memory_budget(MEMORY_FRACTION)
    )
    if on_disk:
        logging.info(
            "the sequences take %.1f GB: training reads them from %s (input_source=%s)",
            total / 1e9,
            workspace.shown(store.folder),
            config.input_source,
        )
        return store.create(shapes)
    return {t: {m: host_arrays.empty(*v) for m, v in d.items()} for t, d in shapes.items()}


def stream_names(lay: archive.Layout) -> dict[str, str]:
    """{modality: how the data names its stream}: a microphone's name, "joints <names> (<fields>)"
    (first–last of more than three joints), and the camera's inputs."""
    out = {m.role: m.name for m in lay.mics if m.role is not None}
    if lay.has_joints:
        j = lay.joint_names
        joints = ", ".join(j) if len(j) <= 3 else f"{j[0]}–{j[-1]}"
        out["proprio"] = f"joints {joints} ({', '.join(lay.joint_fields)})"
    if lay.image_size is not None:
        out.update(image="camera image", flow="camera optical flow")
    return out


def inputs_name(modalities: Sequence[str], names: Mapping[str, str] | None = None) -> str:
    """How tables, figures and printouts name a set of model inputs: by the data's names for its
    streams (`SequenceSet.names`, recorded data: the rig file's microphones and joints) where
    given, else by the paper's sensors (`config.MODALITY_NAMES`), e.g. "Minsound + proprioception"."""
    return " + ".join((names or {}).get(m, MODALITY_NAMES[m]) for m in modalities)


def first_step(meta: dict) -> int:
    """The first rubbing step of a trial (0 for archives that do not record the closing)."""
    return int(meta.get("closing_steps", 0))


def n_sequences(entry: dataset_index.IndexEntry, n: int) -> int:
    return max(entry.n_steps - first_step(entry.meta), 0) // n


def _describe(entries: list[dataset_index.IndexEntry], n: int) -> tuple[dict, dict]:
    """Labels and info of every sequence the entries give, in order."""
    rows = [(e.meta, e.file, first_step(e.meta) + k * n) for e in entries for k in range(n_sequences(e, n))]

    def column(get, dtype) -> np.ndarray:
        return np.array([get(*r) for r in rows], dtype)

    labels = {"fabric": column(lambda m, f, s: m["label"], np.int32)}
    for p in archive.PROPERTY_NAMES:
        labels[p] = column(lambda m, f, s: -1 if m["properties"].get(p) is None else m["properties"][p], np.int32)
    info = {"fabric_id": column(lambda m, f, s: archive.fabric_or_class(m), np.int32)}
    info |= {k: column(lambda m, f, s: -1 if m[k] is None else m[k], np.int32) for k in ("day", "trial")}
    info["start"] = column(lambda m, f, s: s, np.int32)
    info["condition"] = column(lambda m, f, s: m["condition"] or "", str)
    info["trial_key"] = column(lambda m, f, s: f, str)
    return labels, info


def _sequences(
    feature: np.ndarray, modality: str, start: int, n_seq: int, n: int, config: Config, rates: Mapping[str, int]
) -> np.ndarray:
    """A trial's (T, ...) feature -> (n_seq, n, ...) view from step `start`, the remainder dropped."""
    x = _band(feature[start : start + n_seq * n], modality, config.bandwidth_khz, rates, config.mic_window_s)
    return x.reshape(n_seq, n, *x.shape[1:])


def _band(x: np.ndarray, modality: str, bandwidth_khz: float, rates: Mapping[str, int], window_s: float) -> np.ndarray:
    """A feature cut to a bandwidth: a PSD's first `welch.n_bins` bins at its microphone's rate
    and `window_s` windows (the last axis; all of them at or above its Nyquist); other modalities unchanged."""
    if modality not in archive.MIC_ROLES:
        return x
    rate = rates.get(modality, archive.AUDIO_RATE)
    return x[..., : welch.n_bins(bandwidth_khz, rate, welch.window_samples(window_s, rate))]


def step_window_s(
    config: Config, index: dataset_index.DatasetIndex, entries: Sequence[dataset_index.IndexEntry]
) -> float:
    """The microphones' step window [s]: `config.mic_window_s` when set (it wins over the data's,
    said once where they differ), else the one the trials declare (`Layout.mic_window_s`: every
    trial the same, else an error naming the first that differs), else the paper's."""
    declared: dict[float | None, dataset_index.IndexEntry] = {}
    for e in entries:
        declared.setdefault(archive.layout(e.meta).mic_window_s, e)
    if len(declared) > 1:
        (a, ea), (b, eb) = list(declared.items())[:2]
        raise archive.ArchiveError(
            index.path(eb),
            "meta.streams.steps.mic_window_s",
            f"{'absent' if b is None else f'{b:g} s'}, but {'absent' if a is None else f'{a:g} s'} in "
            f"{ea.file} (one step window per dataset)",
        )
    data_s = next(iter(declared))
    if config.mic_window_s is None:
        return PAPER_WINDOW_S if data_s is None else float(data_s)
    if data_s is not None and data_s != config.mic_window_s:
        logging.info(
            "mic_window_s=%g s (the config's) is used, not the %g s the data declares", config.mic_window_s, data_s
        )
    return config.mic_window_s


def narrow(sets: dict[str, SequenceSet], config: Config) -> dict[str, SequenceSet]:
    """Sets loaded for several rows (the union of their modalities, the widest bandwidth) as one
    row's: its modalities only, PSDs cut to its bandwidth. Views, no copies."""
    return {
        k: dataclasses.replace(
            s,
            inputs={
                m: _band(a, m, config.bandwidth_khz, s.rates, s.window_s)
                for m, a in s.inputs.items()
                if m in config.modalities
            },
        )
        for k, s in sets.items()
    }


_SAID: set[tuple] = set()


def _first_time(what: tuple) -> bool:
    """Whether this process has not yet said `what`: a fact of the data (a microphone's rate
    below the band asked for) is said once, not again for every study that loads it."""
    first = what not in _SAID
    _SAID.add(what)
    return first


def _check_bands(config: Config, rates: Mapping[str, int], names: Mapping[str, str], folder=None) -> None:
    """Refuse a step window too short for a spectrum; state a window that gives few bins (a short
    duration at a low rate) and a bandwidth above a microphone's Nyquist (the PSD stops there);
    refuse two microphones whose bands give the shared audio encoder different bin counts.
    `names`: each audio modality's microphone, as the data names it; the bandwidth is said once per
    dataset `folder` and microphone in a process."""
    for m, rate in rates.items():
        window = window_of(config, rate)
        ms, full = 1e3 * config.mic_window_s, welch.full_bins(window)
        if window < welch.MIN_WINDOW:
            raise UserError(
                f"mic_window_s={config.mic_window_s:g}: the {names[m]} microphone's window is {window} "
                f"samples at {rate} Hz, "
                f"too short for a Welch spectrum (at least {welch.MIN_WINDOW} samples)"
            )
        if full < welch.USEFUL_BINS:
            logging.warning(
                "the %s microphone's %.2f ms step window is %d samples at %d Hz: its PSD has only %d bins (0-%g kHz, "
                "%.1f Hz apart); a longer window (--set mic_window_s=..., or the rig file's "
                "steps.mic_window_s) gives a finer spectrum",
                names[m],
                ms,
                window,
                rate,
                full,
                archive.nyquist_khz(rate),
                rate / welch.nperseg(window),
            )
        nyquist = archive.nyquist_khz(rate)
        if config.bandwidth_khz > nyquist and _first_time(("nyquist", str(folder), names[m], config.bandwidth_khz)):
            logging.warning(
                "bandwidth %g kHz is above the %s microphone's Nyquist (%g kHz at %d Hz): its PSD is capped at "
                "0-%g kHz (%d bins)",
                config.bandwidth_khz,
                names[m],
                nyquist,
                rate,
                nyquist,
                full,
            )
    bins = {m: welch.n_bins(config.bandwidth_khz, r, window_of(config, r)) for m, r in rates.items()}
    if len(set(bins.values())) > 1:
        raise UserError(
            f"the microphones' PSDs have different bin counts at {config.bandwidth_khz:g} kHz ({bins}: rates "
            f"{dict(rates)}); "
            "the shared audio encoder needs equal ones: use one microphone, or a bandwidth at or above both Nyquists"
        )


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
    index = dataset_index.load_index(data_dir, workdir)
    classes = classes_of(index)
    n_classes = len(classes)
    roles = splits.assign_roles([e.meta for e in index.entries], presets.get(config.preset).dataset.splits)
    place = lambda e, r: split_of(e.meta, r, config.exclude_fabrics, n_classes)  # noqa: E731
    _report_unused(index.entries, roles, place, n_classes, wanted)
    chosen = [(e, s) for e, r in zip(index.entries, roles) if (s := place(e, r)) in wanted]
    if not chosen:
        raise archive.ArchiveError(
            index.root, "<folder>", f"no trial belongs to the splits {list(wanted)} (check days, conditions and splits)"
        )
    for e, s in chosen:
        if s in ("train", "val") and not 0 <= e.meta["label"] < n_classes:
            raise archive.ArchiveError(
                index.path(e),
                "meta.label",
                f"label {e.meta['label']} of a {s} trial is outside the {n_classes} classes 0..{n_classes - 1}",
            )
    rates = check_streams(index, [e for e, _ in chosen], config.modalities)
    config = dataclasses.replace(config, mic_window_s=step_window_s(config, index, [e for e, _ in chosen]))
    lay = archive.layout(chosen[0][0].meta)
    _check_bands(config, rates, {m: lay.mics[lay.mic(m)].name for m in rates}, index.root)
    n = config.seq_len
    for e, _ in chosen:
        if n_sequences(e, n) == 0:
            raise archive.ArchiveError(
                index.path(e),
                "timestamps",
                f"{e.n_steps} steps of which {e.n_steps - first_step(e.meta)} rubbing, fewer than one "
                f"sequence of N={n} steps",
            )
    members = {s: [e for e, t in chosen if t == s] for s in wanted}
    features = features_for(config, rates)
    store = SequenceStore(
        workspace.sequences_dir(workdir),
        {
            "features": {m: [f.name, f.params] for m, f in features.items()},
            "seq_len": n,
            "bandwidth_khz": config.bandwidth_khz,
            "mic_window_s": config.mic_window_s,
            "rates": rates,
            "dataset": str(index.root.resolve()),
            "trials": {s: [[e.file, e.fingerprint] for e in members[s]] for s in wanted},
            "code": source.fingerprint(SEQUENCE_CODE)[:16],
        },
    )
    inputs = store.load() if config.input_source != "memory" else None
    if (
        inputs is not None
        and config.input_source == "auto"
        and sum(a.nbytes for d in inputs.values() for a in d.values()) <= memo.memory_budget(MEMORY_FRACTION)
    ):
        inputs = None  # stored by a run that asked for "disk", and they fit in memory
    if inputs is None:
        features_root = workspace.features_dir(workdir)
        with lock.hold(
            lock.lock_file(features_root, workdir),
            "the feature cache",
            f"computing features of {index.root.name}",
            wait=True,
        ):
            inputs = _fill(index, chosen, members, features, config, rates, store, features_root, workers, progress)
    names = stream_names(lay)
    return {
        s: SequenceSet(
            inputs[s],
            *_describe(members[s], n),
            rates=rates,
            names=names,
            classes=classes,
            window_s=config.mic_window_s,
            dataset=index.identity(),
        )
        for s in wanted
    }
