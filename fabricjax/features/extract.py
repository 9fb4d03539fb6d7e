"""Per-trial feature arrays, one `Feature` per model input, computed from a `TrialArchive`.

Each feature names the parameters that determine its numbers (`params`), which is what the
cache keys on; a parameter that only selects part of a cached array (the PSD bandwidth) is
applied when sequences are built and is not part of the key. Arrays, per trial of T steps:

    psd_internal, psd_external  float32 (T, 512)         log10 PSD of the microphone whose role is
                                                         internal / external, full band 0 to its
                                                         Nyquist at its own rate (welch.py): 0-24 kHz
                                                         for the hand; the paper's 2048-sample window
    psd_<role>_w<W>             float32 (T, W*511//2048+1) the same over W-sample windows (another
                                                         duration, or the paper's at another rate)
    proprio                     float32 (T, J * F)       joints (T, J, F) flattened joint-major:
                                                         [j0 field 0, j0 field 1, ..., j1 ...]; the
                                                         hand's 6 x (angle, velocity, current):
                                                         archive.N_PROPRIO
    flow                        float16 (T, 2, h, w)     patch-pooled sparse flow (flow.py);
                                                         flow_drop_top: the other reading;
                                                         <either>_jax: dense flow by JAX, not OpenCV
    image_<h>x<w>               uint8   (T, h, w, 3)     area-downsampled frames (images.py; the
                                                         paper's 60x80 unless config.image_size)
    image_session_<h>x<w>       int16   (T, h, w, 3)     the same frames minus their session's
                                                         no-contact reference, downsampled alike,
                                                         in 1/DIFFERENCE_SCALE grey levels
                                                         (images.session_difference)
    image_full                  uint8   (T, H, W, 3)     the archive's frames (not cached)
    image_session_full          int16   (T, H, W, 3)     those minus their session's reference (not cached)
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any, Callable, Mapping

import numpy as np

from fabricjax.config import PAPER_WINDOW_S, Config
from fabricjax.features import flow, images, welch
from fabricjax.store import archive

PSD_CHUNK = 256  # windows per welch call: one compiled shape for every trial length


@dataclasses.dataclass(frozen=True)
class Feature:
    name: str
    params: dict[str, Any]
    needs_images: bool
    cached: bool
    compute: Callable[[archive.TrialArchive], np.ndarray]
    needs_reference: bool = False  # the session's no-contact reference (`archive.TrialArchive.reference`)

    def step_bytes(
        self, frame_size: tuple[int, int], bandwidth_khz: float | None = None, rate: int = archive.AUDIO_RATE
    ) -> int:
        """Bytes one step of this feature's array takes (`step_array`), so that a plan can size the
        cache and the loaded sequences without restating the dtypes."""
        shape, dtype = self.step_array(frame_size, bandwidth_khz, rate)
        return math.prod(shape) * np.dtype(dtype).itemsize

    def step_array(
        self, frame_size: tuple[int, int], bandwidth_khz: float | None = None, rate: int = archive.AUDIO_RATE
    ) -> tuple[tuple[int, ...], np.dtype]:
        """(shape, dtype) of one step of this feature's array, by the module docstring's table, for
        an archive of `frame_size` (H, W) frames; a PSD's bins are those a study keeps of a
        microphone at `rate` Hz (`welch.n_bins` of `bandwidth_khz`; None: all). What a plan times a
        row's training step on, before any data exists."""
        if self.name.startswith("psd_"):
            window = int(m[1]) if (m := re.search(r"_w(\d+)$", self.name)) else archive.WINDOW  # `_psd`'s names
            bins = welch.full_bins(window) if bandwidth_khz is None else welch.n_bins(bandwidth_khz, rate, window)
            return (bins,), np.dtype(np.float32)
        if self.name == "proprio":
            return (archive.N_PROPRIO,), np.dtype(np.float32)
        if self.name.startswith("flow"):
            return (2, *flow.pooled_shape(*frame_size)), np.dtype(np.float16)
        size = self.params.get("size", frame_size)
        return (*size, 3), np.dtype(np.int16 if self.needs_reference else np.uint8)  # int16 against a reference


def mic_index(trial: archive.TrialArchive, role: str) -> int:
    """The `audio` row of the microphone feeding model input `role`; a trial without one is an error."""
    k = archive.layout(trial.meta).mic(role)
    if k is None:
        raise ValueError(f"the trial has no microphone feeding {role!r}: {archive.layout(trial.meta).describe()}")
    return k


def mic_windows(trial: archive.TrialArchive, mic: int, window: int = archive.WINDOW) -> np.ndarray:
    """(T, window) int32: each step's window of raw words from microphone `mic`, the `window`
    samples up to its window end (the paper's 2048 by default).

    A window that would start before the first sample (window_end < window, only possible at the
    very start of a recording) is zero-padded on the left.
    """
    pad = np.concatenate([np.zeros(window, np.int32), trial.audio[mic]])
    idx = trial.window_end[:, mic, None] + np.arange(window)  # shifted by the padding
    return pad[idx]


def log_psd(windows: np.ndarray, rate: int = archive.AUDIO_RATE) -> np.ndarray:
    """(T, W) raw windows of a microphone at `rate` Hz -> (T, welch.full_bins(W)) float32 log10
    PSD over its full band (0 to Nyquist): 512 bins for the paper's 2048-sample windows."""
    n = len(windows)
    padded = np.pad(windows, ((0, -n % PSD_CHUNK), (0, 0)))
    chunks = np.split(padded, len(padded) // PSD_CHUNK)
    out = [
        np.asarray(welch.welch_psd(c, bandwidth_khz=archive.nyquist_khz(rate), floor=welch.LOG_FLOOR, rate=rate))
        for c in chunks
    ]
    return np.concatenate(out)[:n]


def _trial_psd(trial: archive.TrialArchive, role: str, window: int) -> np.ndarray:
    k = mic_index(trial, role)
    return log_psd(mic_windows(trial, k, window), archive.layout(trial.meta).mics[k].rate)


def _psd(role: str, window: int) -> Feature:
    """The PSD over `window`-sample windows. The paper's 2048 keeps its name and cache key (its
    numbers are unchanged); SCIPY_KWARGS' fs is the hand's 48 kHz, while another rig's microphone
    is analysed at its own rate, which its archive (and so the cache's archive fingerprint)
    records. Another window is another feature, with its own name and key."""
    if window == archive.WINDOW:
        params = {"mic": role, **welch.SCIPY_KWARGS, "log10_floor": welch.LOG_FLOOR}
        return Feature(f"psd_{role}", params, False, True, lambda t: _trial_psd(t, role, window))
    kwargs = {k: v for k, v in welch.scipy_kwargs(window).items() if k != "fs"}  # fs: the archive's rate
    params = {"mic": role, "window": window, **kwargs, "log10_floor": welch.LOG_FLOOR}
    return Feature(f"psd_{role}_w{window}", params, False, True, lambda t: _trial_psd(t, role, window))


def _proprio(trial: archive.TrialArchive) -> np.ndarray:
    return trial.joints.reshape(trial.n_steps, -1).astype(np.float32)


def feature_for(
    modality: str,
    image_resolution: str = "down",
    image_size: tuple[int, int] = images.DOWN_SIZE,
    flow_sparsify: str = "keep_top",
    window: int = archive.WINDOW,
    image_reference: str = "session",
    flow_method: str = "opencv",
) -> Feature:
    """The feature behind a model input (a `config.MODALITIES` name); `image_size` is the
    downsampled ("down") frame size, `flow_sparsify` the flow's reading of the paper's filter
    (`flow.SPARSIFY`: "flow" is the default reading's feature, "flow_<reading>" another's),
    `window` a microphone's step window in samples (`welch.window_samples`), `image_reference`
    what a frame is read against (`config.IMAGE_REFERENCES`: "session" is its own feature, the
    others subtract in the model), `flow_method` who computes the dense flow (`flow.METHODS`:
    OpenCV's keeps its name and cache key, "jax" is its own feature, "<name>_jax")."""
    if modality in archive.MIC_ROLES:
        return _psd(modality, window)
    if modality == "proprio":
        return Feature("proprio", {}, False, True, _proprio)
    if modality == "flow":
        params = {"farneback": flow.FARNEBACK, "top_fraction": flow.TOP_FRACTION, "patch": flow.PATCH}
        if flow_sparsify != flow.SPARSIFY[0]:  # the default reading keeps its name and cache key
            params["sparsify"] = flow_sparsify
        name = "flow" if flow_sparsify == flow.SPARSIFY[0] else f"flow_{flow_sparsify}"
        if flow_method != flow.METHODS[0]:  # OpenCV's flow keeps its name and cache key
            params["method"] = flow_method
            name = f"{name}_{flow_method}"
        return Feature(name, params, True, True, lambda t: flow.trial_flow(t.images, flow_sparsify, method=flow_method))
    if modality == "image" and image_resolution == "down" and image_reference == "session":
        size = (int(image_size[0]), int(image_size[1]))
        params = {"size": size, "interpolation": "area", "reference": "session"}
        return Feature(
            f"image_session_{size[0]}x{size[1]}",
            params,
            True,
            True,
            lambda t: images.session_difference(t.images, t.reference, size),
            True,
        )
    if modality == "image" and image_resolution == "full" and image_reference == "session":
        return Feature(
            "image_session_full",
            {"reference": "session"},
            True,
            False,
            lambda t: images.session_difference(t.images, t.reference, None),
            True,
        )
    if modality == "image" and image_resolution == "down":
        size = (int(image_size[0]), int(image_size[1]))
        params = {"size": size, "interpolation": "area"}
        return Feature(f"image_{size[0]}x{size[1]}", params, True, True, lambda t: images.downsample(t.images, size))
    if modality == "image" and image_resolution == "full":
        return Feature("image_full", {}, True, False, lambda t: t.images)
    raise ValueError(f"no feature for modality {modality!r} at image resolution {image_resolution!r}")


def window_of(config: Config, rate: int) -> int:
    """A microphone's step window in samples at `rate` Hz: the config's duration (2048 for the hand;
    a config that leaves it to the data, mic_window_s None, and has not been fitted to one gets the paper's)."""
    return welch.window_samples(PAPER_WINDOW_S if config.mic_window_s is None else config.mic_window_s, rate)


def features_for(config: Config, rates: Mapping[str, int] | None = None) -> dict[str, Feature]:
    """The feature behind each of `config.modalities`, as `config` computes it. `rates`: each audio
    modality's microphone rate [Hz] (`data.check_streams`), which with `config.mic_window_s` sets its
    window (`window_of`); a modality it lacks, or every one where it is None, gets the paper's
    2048-sample window (`archive.WINDOW`), which is no part of a camera or joint feature."""
    rates = rates or {}
    return {
        m: feature_for(
            m,
            config.image_resolution,
            config.image_size,
            config.flow_sparsify,
            window_of(config, rates[m]) if m in rates else archive.WINDOW,
            config.image_reference,
            config.flow_method,
        )
        for m in config.modalities
    }


def feature_named(name: str) -> Feature:
    """The feature called `name` (how a worker process rebuilds one: a Feature's function does
    not pickle)."""
    if m := re.fullmatch(r"image_session_(\d+)x(\d+)", name):
        return feature_for("image", "down", (int(m[1]), int(m[2])), image_reference="session")
    if m := re.fullmatch(r"image_(\d+)x(\d+)", name):
        return feature_for("image", "down", (int(m[1]), int(m[2])), image_reference="training_mean")
    if m := re.fullmatch(r"psd_(\w+)_w(\d+)", name):
        return feature_for(m[1], window=int(m[2]))
    candidates = [feature_for(m) for m in (*archive.MIC_ROLES, "proprio")] + [
        feature_for("image", "full", image_reference=r) for r in ("none", "session")
    ]
    candidates += [
        feature_for("flow", flow_sparsify=mode, flow_method=method) for mode in flow.SPARSIFY for method in flow.METHODS
    ]
    for f in candidates:
        if f.name == name:
            return f
    raise ValueError(f"no feature named {name!r}")
