"""The input pipeline between the data and the model: what the model's inputs are standardised
by, and the layout training holds its sets in.

    STANDARDISED / per_position_shift / per_position_scale / shift_shape / scale_shape / channel_shape
                          which inputs are standardised, along which channel axis, and the shapes
                          of their fixed (shift, scale) parameters in `model.FabricNet`
    input_statistics      those parameters' values from the training split
    with_input_statistics a model's parameters with them written in
    training_layout       a set's inputs as training and its evaluation read them (frames as rows)
    training_input        one input of it
    feature_shapes        the per-step shapes a model is built for

`data` produces the arrays, `model` reads them; `train` uses both through this module.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any, Mapping

import jax
import jax.numpy as jnp
import numpy as np

from fabricjax import host_arrays, memo, runtime
from fabricjax.config import Config
from fabricjax.features import images

# Inputs standardised per channel with fixed training-split statistics, and the axis of a per-step
# input (no batch or step axes) that holds their channels: joint values, colour, flow component.
STANDARDISED = {"proprio": -1, "image": -1, "flow": 0}


def standardised_channels(modality: str, step_shape: tuple[int, ...]) -> int:
    return step_shape[STANDARDISED[modality]]


def per_position_shift(config: Config, modality: str) -> bool:
    """Whether `modality`'s shift is a whole reference frame (one value per pixel and colour,
    `config.image_reference`, or each pixel's own mean under `config.image_standardisation`) rather
    than one value per channel."""
    return modality == "image" and (config.image_reference == "training_mean" or per_position_scale(config, modality))


def per_position_scale(config: Config, modality: str) -> bool:
    """Whether `modality`'s scale is one value per pixel and colour (`config.image_standardisation`)
    rather than one value per channel."""
    return modality == "image" and config.image_standardisation == "pixel"


def shift_shape(config: Config, modality: str, step_shape: tuple[int, ...]) -> tuple[int, ...]:
    return tuple(step_shape) if per_position_shift(config, modality) else (standardised_channels(modality, step_shape),)


def scale_shape(config: Config, modality: str, step_shape: tuple[int, ...]) -> tuple[int, ...]:
    return tuple(step_shape) if per_position_scale(config, modality) else (standardised_channels(modality, step_shape),)


def channel_shape(modality: str, ndim: int) -> tuple[int, ...]:
    """Broadcast shape of per-channel statistics against a (M, ...) batch of `ndim` per-step axes."""
    shape = [1] * (ndim + 1)
    shape[STANDARDISED[modality] % ndim + 1] = -1
    return tuple(shape)


def feature_shapes(inputs: Mapping[str, jax.Array]) -> dict[str, tuple[int, ...]]:
    """Per-step shapes of a batch (drop the leading batch and step axes): what the model is built for."""
    return {k: tuple(v.shape[2:]) for k, v in inputs.items()}


# Bytes of a split summed at a time by `input_statistics` (one chunk per core at a time), so that
# its temporaries (float64 or uint16 copies) can stay in the caches. Profiling has not shown the
# chunk size to matter beyond run-to-run variation; both cores summing matters more.
CHUNK_BYTES = 4 << 20


def input_statistics(config: Config, train_set, chunk: int | None = None) -> dict[str, jax.Array]:
    """The model's fixed input standardisation (`STANDARDISED`) from the (unpadded) training
    split: per channel, the mean and 1 / SD over every sequence, step and position; for images
    read from a reference frame (`per_position_shift`), the mean frame (per pixel and colour)
    and 1 / SD of the frames' difference to it, per colour, or per pixel and colour
    (`per_position_scale`). Accumulated on the host in float64 over
    chunks of sequences (`chunk`; default: as many as fit `CHUNK_BYTES`), so a camera split (GBs
    of uint8 frames) is never copied whole into float32."""
    inputs = train_set["inputs"] if isinstance(train_set, Mapping) else train_set.inputs
    stats = {}
    for m in config.modalities:
        if m not in STANDARDISED:
            continue
        x = inputs[m]
        axis = STANDARDISED[m] % (x.ndim - 2) + 2  # the channel axis of (S, N, ...)
        per_position = per_position_shift(config, m), per_position_scale(config, m)
        n = chunk or max(1, CHUNK_BYTES // max(x[0].nbytes, 1))
        mean, variance = _STATISTICS.get(x, (axis, *per_position, n), lambda: _moments(x, axis, *per_position, n))
        stats[f"{m}_shift"] = jnp.asarray(mean, jnp.float32)
        stats[f"{m}_scale"] = jnp.asarray(1.0 / np.maximum(np.sqrt(variance), 1e-6), jnp.float32)
    return stats


# The statistics of a loaded training array, kept for the study's next row on it (`memo`).
_STATISTICS = memo.ByArray(max_entries=16)


def _moments(x, axis: int, per_position: bool, per_position_variance: bool, chunk: int) -> tuple[np.ndarray, ...]:
    """(mean, variance) of `x` (S, N, ...) about each channel's mean, or each position's
    (`per_position`), summed over chunks of `chunk` sequences along the channel `axis`; the
    variance per channel, or per position and channel (`per_position_variance`). The chunks
    are summed on every core (NumPy's reductions release the GIL) and their sums added in order,
    so the result does not depend on the number of cores."""
    total, total_sq, count = 0.0, 0.0, 0
    with ThreadPoolExecutor(runtime.available_cores()) as pool:
        sums = pool.map(
            lambda start: _sums(np.asarray(x[start : start + chunk]), axis), range(0, max(len(x), 1), chunk)
        )
        for part_sums in sums:
            total, total_sq, count = (a + b for a, b in zip((total, total_sq, count), part_sums))
    mean, mean_sq = total / max(count, 1), total_sq / max(count, 1)  # per position and channel
    positions = tuple(range(mean.ndim - 1))
    if per_position:  # spread about each position's own mean
        variance = np.maximum(mean_sq - mean * mean, 0.0)
        return mean, variance if per_position_variance else variance.mean(positions)
    mean, mean_sq = mean.mean(positions), mean_sq.mean(positions)
    return mean, np.maximum(mean_sq - mean * mean, 0.0)


def _sums(part: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Sums of `part` (S, N, ...) and of its squares over sequences and steps, float64, with the
    channel `axis` moved last, and the count S x N. Frames (8-bit, or their 16-bit differences to a
    reference) are summed in integers (squares fit uint16 or int32, sums int64) and converted after: every partial sum
    is an integer below 2**53, so
    float64 summation is exact too and the two agree bit for bit, at a fraction of the float64
    copy's time and memory."""
    if part.dtype in (np.uint8, np.int16):  # frames, and frames minus their session's reference (|x| < 2**14)
        flat = part.reshape(-1, *part.shape[2:])
        wide = flat.astype(np.uint16 if part.dtype == np.uint8 else np.int32)
        sums = (
            np.moveaxis(a, axis - 2, -1).astype(np.float64)
            for a in (flat.sum(0, dtype=np.int64), (wide * wide).sum(0, dtype=np.int64))
        )
        return (*sums, len(flat))
    part = np.moveaxis(np.asarray(part, np.float64), axis, -1)
    part = part.reshape(-1, *part.shape[2:])  # (sequences x steps, positions..., channels)
    return part.sum(0), (part * part).sum(0), len(part)


def with_input_statistics(params: dict[str, Any], stats: Mapping[str, jax.Array]) -> dict[str, Any]:
    """`params` (one seed's, or stacked over seeds) with the input statistics written into them."""
    return {**params, **{k: jnp.broadcast_to(v, params[k].shape).astype(params[k].dtype) for k, v in stats.items()}}


def training_layout(inputs: Mapping[str, jax.Array]) -> dict[str, jax.Array]:
    """A data set's inputs as training and its evaluation read them: frames ("image", (S, N, H, W,
    C)) as rows ("image_rows", (S, H*W, C, N): `features.images.to_rows`), so that each minibatch's
    rotation moves whole rows (`FabricNet.image_features`) and evaluation runs the same compiled
    image path; other inputs unchanged. `train_and_evaluate` does it once per set, on the whole
    set, on the host (NumPy in, NumPy out), before it goes to the devices, so that the transpose
    stays out of the training step."""
    return dict(training_input(m, a) for m, a in inputs.items())


def training_input(modality: str, array, length: int | None = None) -> tuple[str, Any]:
    """One input as `training_layout` holds it: (its name there, the array), with zero inputs
    appended up to `length` sequences where one is given (NumPy arrays: evaluation sets run in
    whole minibatches)."""
    if modality == "image":
        return "image_rows", images.to_rows(array, length)
    return modality, array if length is None else host_arrays.padded(array, length, 0)
