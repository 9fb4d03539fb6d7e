"""Random data sets in the training batch format, for tests and benchmarks (no simulator needed).

Every modality carries a small class-dependent offset so that a model can learn something.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from fabricjax import catalog
from fabricjax.config import Config
from fabricjax.features import images
from fabricjax.store import archive


def data_set(
    config: Config,
    n: int,
    *,
    seq_len: int | None = None,
    psd_bins: int = 24,
    flow_hw: tuple[int, int] = (25, 34),
    image_hw: tuple[int, int] = (60, 80),
    seed: int = 0,
) -> dict[str, dict[str, np.ndarray]]:
    """{"inputs": {modality: (n, N, ...)}, "labels": {fabric, stretchiness, roughness, thickness}}."""
    rng = np.random.default_rng(seed)
    steps = seq_len or config.seq_len
    fabric = rng.integers(0, catalog.N_CLASSES, n)
    shift = (fabric / catalog.N_CLASSES).astype(np.float32)[:, None, None]
    shapes = {
        "internal": (psd_bins,),
        "external": (psd_bins,),
        "proprio": (archive.N_PROPRIO,),
        "flow": (2, *flow_hw),
        "image": (*image_hw, 3),
    }
    inputs = {}
    for m in config.modalities:
        x = rng.normal(size=(n, steps, *shapes[m])).astype(np.float32)
        x += shift.reshape(n, 1, *([1] * len(shapes[m])))
        inputs[m] = np.clip(x * 40 + 128, 0, 255).astype(np.uint8) if m == "image" else x
    labels = {"fabric": fabric.astype(np.int32)}
    for prop, levels in catalog.PROPERTY_LEVELS.items():
        labels[prop] = (fabric % levels).astype(np.int32)
    return {"inputs": inputs, "labels": labels}


def shaped(
    arrays: Mapping[str, tuple[tuple[int, ...], Any]], n: int, seq_len: int, *, n_classes: int, seed: int = 0
) -> dict[str, dict[str, np.ndarray]]:
    """A data set of `n` sequences of `seq_len` steps whose inputs have exactly the per-step
    (shape, dtype) of `arrays` ({modality: ...}, as `Feature.step_array` gives them) and fabric labels
    in 0..n_classes-1: what a row's step is timed on before its data exists. Its values are noise
    (timing does not depend on them); integer frames spread over their type's range."""
    rng = np.random.default_rng(seed)
    inputs = {}
    for m, (shape, dtype) in arrays.items():
        x = rng.normal(size=(n, seq_len, *shape))
        dtype = np.dtype(dtype)
        if dtype.kind in "iu":
            info = np.iinfo(dtype)
            x = np.clip(x * 40 + (info.min + info.max) / 2, info.min, info.max)
        inputs[m] = x.astype(dtype)
    fabric = rng.integers(0, n_classes, n)
    labels = {"fabric": fabric.astype(np.int32)}
    labels.update({prop: (fabric % levels).astype(np.int32) for prop, levels in catalog.PROPERTY_LEVELS.items()})
    return {"inputs": inputs, "labels": labels}


# Positive controls: one stream carries a planted class cue, every other stream is noise. A model
# that cannot learn such a cue from a stream cannot be trusted to report that a real stream is
# uninformative (a row at chance is the model's fault until its control passes).
CUE_KINDS = ("static", "dynamic")


def _cue(kind: str, labels: np.ndarray, steps: int, n_classes: int, rng) -> np.ndarray:
    """(n, steps) cue in [0, 1] per sequence.

    static:  a level constant over the sequence, class c at c / (n_classes - 1).
    dynamic: a pulse: the cue is 1 for a run of round((c + 1) / (n_classes + 1) * steps) steps
             starting at a random step (wrapping around) and 0 elsewhere, so every class has the
             same per-sequence minimum (0) and maximum (1): only the time spent high tells
             classes apart, which is what survives the paper's [0, 1] rescale over the sequence
             (a sensor's steady level does not)."""
    n = len(labels)
    if kind == "static":
        return np.repeat((labels / max(n_classes - 1, 1))[:, None], steps, axis=1).astype(np.float32)
    if kind != "dynamic":
        raise ValueError(f"cue kind must be one of {CUE_KINDS}, got {kind!r}")
    if steps < n_classes + 1:
        raise ValueError(f"a dynamic cue for {n_classes} classes needs at least {n_classes + 1} steps, got {steps}")
    high = np.clip(np.round((labels + 1) / (n_classes + 1) * steps), 1, steps - 1).astype(int)
    t = (np.arange(steps)[None, :] - rng.integers(0, steps, n)[:, None]) % steps
    return (t < high[:, None]).astype(np.float32)


def planted_cue(
    config: Config,
    cued: str,
    kind: str,
    n: int,
    *,
    n_classes: int = 4,
    psd_bins: int = 24,
    flow_hw: tuple[int, int] = (15, 20),
    image_hw: tuple[int, int] = (24, 32),
    seed: int = 0,
) -> dict[str, dict[str, np.ndarray]]:
    """A data set in the training format where only modality `cued` carries the fabric label
    (classes 0..n_classes-1) through a `kind` cue (`_cue`); every modality also carries
    per-step noise. The cue's strength is of the order of the noise, so a model must average over
    steps (or pixels) to read it.

        image     a centred disc (radius a third of the frame's height) brightens with the cue by
                  0 -> 64 grey levels on pixel noise of SD 24, over a fixed colour field (each
                  colour a ramp of 40 -> 200 across the frame in its own direction, the same for
                  every sequence, as the shell's LEDs light a Minsight frame): the disc's
                  brightening is invariant to rotation about the centre, the field is not;
                  with `config.image_reference` "session", the frames minus that field (int16, in
                  `images.DIFFERENCE_SCALE` steps per grey level), as the data reads frames minus
                  their session's no-contact reference
        flow      a uniform flow of 0 -> 1 px/frame along x over the frame's centre third, on
                  noise of SD 0.5 px/frame
        internal / external   log-PSD bins 4-11 rise by 0 -> 1 (decades) over noise of SD 0.5
        proprio   every joint value rises by 0 -> 1 over unit noise (a load shows in every joint)
    """
    if cued not in config.modalities:
        raise ValueError(f"the cued modality {cued!r} is not among {config.modalities}")
    rng = np.random.default_rng(seed)
    steps = config.seq_len
    labels = rng.integers(0, n_classes, n)
    cue = _cue(kind, labels, steps, n_classes, rng)  # (n, steps)
    inputs = {}
    for m in config.modalities:
        on = cue if m == cued else np.zeros_like(cue)
        if m == "image":
            h, w = image_hw
            yy, xx = np.mgrid[:h, :w]
            disc = ((yy - (h - 1) / 2) ** 2 + (xx - (w - 1) / 2) ** 2 <= (h / 3) ** 2).astype(np.float32)
            field = np.stack([40 + 160 * ramp for ramp in (xx / (w - 1), yy / (h - 1), 1 - xx / (w - 1))], axis=-1)
            x = field + 64 * on[:, :, None, None, None] * disc[None, None, :, :, None]
            x = x + rng.normal(0, 24, (n, steps, h, w, 3))
            inputs[m] = np.clip(x, 0, 255).astype(np.uint8)
            if config.image_reference == "session":
                difference = (inputs[m] - field) * images.DIFFERENCE_SCALE
                inputs[m] = np.rint(difference).astype(np.int16)
        elif m == "flow":
            h, w = flow_hw
            x = rng.normal(0, 0.5, (n, steps, 2, h, w)).astype(np.float32)
            x[:, :, 0, h // 3 : 2 * h // 3, w // 3 : 2 * w // 3] += on[:, :, None, None]
            inputs[m] = x
        elif m == "proprio":
            x = rng.normal(0, 1, (n, steps, archive.N_PROPRIO)).astype(np.float32)
            x += on[:, :, None]
            inputs[m] = x
        else:
            x = rng.normal(-8, 0.5, (n, steps, psd_bins)).astype(np.float32)
            x[:, :, 4:12] += on[:, :, None]
            inputs[m] = x
    return {"inputs": inputs, "labels": {"fabric": labels.astype(np.int32)}}
