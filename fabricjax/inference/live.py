"""Live classification: a rolling window of features, updated for the newest step only.

    streamer = Streamer(graphdef, params, config)     # a trained model and its config
    report = replay(streamer, trial, realtime=True)   # a TrialArchive, step by step at 50 Hz

The command (`python -m experiments.stream`: a quick model or a checkpoint, a trial, the live
printout and results/stream.json) is `fabricjax.studies.diagnostics.stream`.

Every step brings one window per microphone, the config's step window at that microphone's rate
(`data.window_of`: 2048 samples for the hand), and the joint values (the hand's `archive.N_PROPRIO`,
or the data's joints x fields: the `layout` the streamer is given). One jitted update computes the
Welch PSD of just those windows (`welch_psd` of each microphone's window at its rate, at the
config's bandwidth), shifts the (N, F) windows by one step on the device (the oldest
step drops out, buffers donated), and runs the model over the window. Nothing of the window is recomputed:
the PSD of a step is computed once, when it arrives, and equals the batch feature of
`features.extract.log_psd` for that step. The model itself does run over the whole window each
step: its per-sequence [0, 1] rescale and attention see every step.

A decision needs a full window (N steps, N / 50 Hz seconds of touch): the model's position
embedding has exactly N entries and one compiled shape keeps the update fast. The first N - 1
steps only fill the window (the same update runs, its prediction is not reported).

Per-step latency is host-to-host: from the step's raw data in hand (slicing its windows out of
the recording, as a live reader would out of its ring buffer) to the class probabilities on the
host. Only audio and proprioception stream; image and flow models are rejected.

The probabilities are calibrated by the model's temperature (`confidence`, fitted by
`experiments.decide` and kept beside the checkpoint; 1 where none was fitted). `replay` also
accumulates the evidence of successive non-overlapping windows (every N-th step once the window is
full) into a posterior (`confidence.Accumulator`) and names the step at which the sequential rule
would decide (the best class's posterior reaching `confidence.DECISION_THRESHOLD`).
"""

from __future__ import annotations

import dataclasses
import functools
import time
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from fabricjax import catalog
from fabricjax.config import Config
from fabricjax.features import welch
from fabricjax.inference import confidence
from fabricjax.reporting import stats
from fabricjax.sequences import data
from fabricjax.store import archive

STREAMABLE = ("internal", "external", "proprio")
HAND = archive.layout(
    {"format_version": archive.FORMAT_VERSION, "streams": archive.hand_streams(None)}
)  # the paper's hand's streams


@dataclasses.dataclass(frozen=True)
class StepResult:
    step: int
    time_s: float  # since the trial's first step
    probs: np.ndarray | None  # None while the window fills
    latency_ms: float
    posterior: np.ndarray | None = None  # accumulated over the non-overlapping windows so far
    windows: int = 0  # windows accumulated
    decided: bool = False  # the sequential rule has decided at this step or before


class Streamer:
    """A model and its rolling window; `update` consumes one step. `layout`: the streams of the
    trials it is fed (`archive.layout` of their meta; default the hand's), which give each
    microphone's row and rate and the joint values per step."""

    def __init__(
        self, graphdef: nnx.GraphDef, params, config: Config, temperature: float = 1.0, layout: archive.Layout = HAND
    ):
        bad = [m for m in config.modalities if m not in STREAMABLE]
        if bad:
            raise ValueError(f"streaming supports the modalities {STREAMABLE}; the model uses {bad}")
        if not config.fabric_head:
            raise ValueError("streaming classifies fabrics: the model needs its fabric head")
        self.config, self.temperature = config, float(temperature)
        self.n = config.seq_len
        self.mics = [layout.mic(m) for m in config.modalities if m in archive.MIC_ROLES]
        if None in self.mics:
            raise ValueError(f"the model reads {'+'.join(config.modalities)}; the data has {layout.describe()}")
        self.rates = tuple(layout.mics[k].rate for k in self.mics)
        self.windows = tuple(data.window_of(config, r) for r in self.rates)  # samples per step, each mic at its rate
        self.joint_shape = (len(layout.joint_names), len(layout.joint_fields))
        # Everything on one device: restored parameters may carry the training mesh's sharding, and
        # a sharding that changed between steps would recompile the update mid-stream.
        self.device = jax.devices()[0]
        self.params = jax.device_put(params, self.device)
        width = dict(
            zip(
                [m for m in config.modalities if m in archive.MIC_ROLES],
                (welch.n_bins(config.bandwidth_khz, r, w) for r, w in zip(self.rates, self.windows)),
            )
        )
        width["proprio"] = int(np.prod(self.joint_shape))
        self._empty = {m: np.zeros((self.n, width[m]), np.float32) for m in config.modalities}
        self._update = jax.jit(
            functools.partial(_update, graphdef, config, self.temperature, self.rates), donate_argnums=1
        )
        self.reset()

    def reset(self) -> None:
        """An empty window."""
        self.window, self.steps = jax.device_put(self._empty, self.device), 0

    def warmup(self) -> None:
        """Compile the update and run it twice (first window and steady state), then reset."""
        for _ in range(2):
            self.update([np.zeros(w, np.int32) for w in self.windows], np.zeros(self.joint_shape, np.float32))
        self.reset()

    def update(self, mic_windows: list[np.ndarray], joints: np.ndarray) -> np.ndarray | None:
        """Push one step (each of the model's microphones' int32 raw words over its window, `windows`:
        2048 for the hand; (joints, fields) values, the hand's (6, 3)); returns the class
        probabilities once the window is full, else None."""
        self.window, probs = self._update(self.params, self.window, mic_windows, joints)
        self.steps += 1
        probs = np.asarray(probs)  # waits for the step, full window or not
        return probs if self.steps >= self.n else None


def _update(graphdef, config: Config, temperature: float, rates: tuple[int, ...], params, window, mic_windows, joints):
    """(new window, calibrated class probabilities of the model over it)."""
    psds = iter([welch.welch_psd(w, bandwidth_khz=config.bandwidth_khz, rate=r) for w, r in zip(mic_windows, rates)])
    new = {}
    for m in config.modalities:
        x = joints.reshape(-1).astype(jnp.float32) if m == "proprio" else next(psds)
        new[m] = jnp.concatenate([window[m][1:], x[None]])
    logits = nnx.merge(graphdef, params)({m: w[None] for m, w in new.items()})["fabric"][0]
    return new, jax.nn.softmax(logits / temperature)


def step_windows(trial: archive.TrialArchive, step: int, mics: list[int], windows: list[int]) -> list[np.ndarray]:
    """The step's raw int32 window of each microphone `mics[i]`, `windows[i]` samples (a
    streamer's `windows`), zero-padded on the left at the very start of a recording (as
    `features.extract.mic_windows`)."""
    out = []
    for mic, w in zip(mics, windows):
        end = int(trial.window_end[step, mic])
        part = trial.audio[mic, max(0, end - w) : end]
        out.append(np.concatenate([np.zeros(w - len(part), np.int32), part]))
    return out


def class_name(label: int, meta: dict | None = None) -> str:
    """A class's name: from the label map of a trial's `meta` where it has one, else the catalog's fabric."""
    named = None if meta is None else data.label_classes(meta)
    if named is not None:
        return named[label] if 0 <= label < len(named) else f"class {label}"
    return catalog.fabric(label).name if 0 <= label < catalog.N_CLASSES else f"class {label}"


def replay(
    streamer: Streamer,
    trial: archive.TrialArchive,
    *,
    realtime: bool = True,
    on_step: Callable[[StepResult], None] | None = None,
    max_steps: int | None = None,
) -> dict:
    """Feed a recorded trial to `streamer` step by step (at the trial's step rate, meta
    streams.steps.rate, when `realtime`, else as fast as possible) after one warm-up update, and
    summarise: time to the first correct decision, accuracy over decided steps, per-step latency
    p50 / p99, in real time the steps whose result came after the end of their slot (20 ms at
    50 Hz; this also counts the OS waking the sleeping loop late), and the sequential decision
    over the accumulated windows (`decision`: its step, time, class, posterior; None if the trial
    ended first)."""
    label = int(trial.meta["label"])
    n_steps = min(trial.n_steps, max_steps or trial.n_steps)
    stamps = trial.timestamps - trial.timestamps[0]
    period = 1.0 / archive.layout(trial.meta).step_rate  # an imported 30 fps camera: 33 ms
    seconds, correct, first_correct, late = [], [], None, 0
    evidence, decision = confidence.Accumulator(confidence.DECISION_THRESHOLD), None
    streamer.warmup()
    start = time.perf_counter()
    for t in range(n_steps):
        if realtime:
            wait = start + t * period - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
        t0 = time.perf_counter()
        joints = (
            np.zeros(streamer.joint_shape, np.float32) if trial.joints is None else trial.joints[t]
        )  # a rig without joints
        probs = streamer.update(step_windows(trial, t, streamer.mics, streamer.windows), joints)
        done = time.perf_counter()
        ms = 1e3 * (done - t0)
        if realtime and done > start + (t + 1) * period:
            late += 1
        if probs is not None:
            seconds.append(done - t0)
            ok = int(np.argmax(probs)) == label
            correct.append(ok)
            if ok and first_correct is None:
                first_correct = t
            if (streamer.steps - streamer.n) % streamer.n == 0:  # a window not overlapping the ones before
                evidence.add(probs)
                if decision is None and evidence.decided:
                    k = int(np.argmax(evidence.posterior))
                    decision = {
                        "step": t,
                        "time_s": float(stamps[t] + period),
                        "windows": evidence.windows,
                        "class": k,
                        "fabric": class_name(k, trial.meta),
                        "posterior": float(evidence.posterior[k]),
                        "correct": k == label,
                    }
        if on_step is not None:
            on_step(
                StepResult(
                    t,
                    float(stamps[t]),
                    probs,
                    ms,
                    None if evidence.log_post is None else evidence.posterior,
                    evidence.windows,
                    decision is not None,
                )
            )
    latency = stats.percentiles_ms(seconds) if seconds else {"p50_ms": None, "p99_ms": None}
    return {
        "label": label,
        "fabric": class_name(label, trial.meta),
        "steps": n_steps,
        "window_steps": streamer.n,
        "decided_steps": len(correct),
        "accuracy_over_decided_steps": float(np.mean(correct)) if correct else None,
        "first_correct_step": first_correct,
        "time_to_first_correct_s": None if first_correct is None else float(stamps[first_correct] + period),
        "latency_p50_ms": latency["p50_ms"],
        "latency_p99_ms": latency["p99_ms"],
        "latency_max_ms": 1e3 * max(seconds) if seconds else None,
        "realtime": realtime,
        "late_steps": late if realtime else None,
        "temperature": streamer.temperature,
        "decision_threshold": confidence.DECISION_THRESHOLD,
        "decision": decision,
    }


def restore_model(directory) -> tuple[nnx.GraphDef, dict, Config, float]:
    """(graphdef, best-validation params of the first seed, config, temperature) of a
    `train_and_evaluate` checkpoint, under the config saved with it; the temperature is the one
    fitted for that seed (`confidence.load_temperature`), 1 where none was. A checkpoint of a model
    that cannot stream (no fabric head, or inputs other than `STREAMABLE`) is a
    `checkpoint.WrongCheckpoint`."""
    from fabricjax.training import checkpoint, train

    restored = train.restore(directory)
    for_ = restored.trained_for
    checkpoint.require(
        directory,
        for_,
        "streaming",
        f"a model with a fabric head over inputs from {'/'.join(STREAMABLE)}",
        "fabric" in for_["heads"] and set(for_["inputs"]) <= set(STREAMABLE),
    )
    t = confidence.load_temperature(directory, restored.seeds[0])
    return (
        restored.graphdef,
        checkpoint.select_seed(restored.state.best_params, 0),
        restored.config,
        1.0 if t is None else t,
    )
