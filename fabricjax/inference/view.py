"""A trial on one Rerun timeline: what the hand sensed, what the model's inputs look like, and
what a model made of it, step by step.

Every step is logged at timeline "step" (the 50 Hz step index) and "time" (seconds since the
trial's first step), under these entity paths:

    minsight/frame             Image     the Minsight frame (when the trial has frames)
    minsight/reference         Image     its session's no-contact reference (archives of format 3;
                                         logged at the first step)
    minsight/difference        Image     the frame minus that reference, what `image_reference=
                                         "session"` reads: mid-grey = no change, per colour
    minsight/flow              Image     the flow modality's input: the step's optical flow, top
                                         0.1 % by magnitude, 3x3-pooled (`features.flow`); hue =
                                         direction, brightness = magnitude (the frame's largest = full)
    audio/<mic>/spectrogram    Image     log10 PSD (`features.welch`, 0-24 kHz, low frequencies at
                                         the bottom) of the last `SPECTROGRAM_STEPS` steps, newest
                                         at the right: a scrolling spectrogram, colour range = its own
    audio/<mic>/wave           Scalars   the raw waveform in full-scale units, one point per sample
                                         (timeline "time" only: the samples new at each step)
    joints/<joint>/<field>     Scalars   every joint's angle (rad), velocity (rad/s), current (A)
    force                      Scalars   the force proxy, N
    prediction/probabilities   BarChart  a model's class probabilities over the window ending here
    prediction/confidence      Scalars   the predicted class's probability
    prediction/class           TextLog   the predicted fabric (and whether it is right)
    prediction/latency_ms      Scalars   the step's host-to-host latency (`live.Streamer`)

<mic> is "internal" (Minsound) or "external" (palm). Prediction entities come from a model
streaming over the trial (`live.replay`): the first N - 1 steps only fill its window and log
just the latency. The same `TrialView` serves a recorded trial (`log_trial`, `experiments.view`),
the live streaming classifier (`experiments.stream --view`) and the recorder
(`acquisition.record --view`).

rerun-sdk is an optional extra (`pip install -e ".[viz]"`), imported only here.
"""

from __future__ import annotations

import dataclasses
import os
import sys
from typing import Any

import numpy as np

from fabricjax.errors import UserError
from fabricjax.features import flow, welch
from fabricjax.inference import false_colour, live
from fabricjax.store import archive

EXTRA = 'pip install -e ".[viz]"'
APPLICATION_ID = "fabricjax"
SPECTROGRAM_STEPS = 100  # 2 s at 50 Hz


def rerun():
    """The rerun module, or a one-line user error saying how to install it."""
    try:
        import rerun as rr
    except ImportError:
        raise UserError(f"viewing needs the Rerun SDK: {EXTRA}") from None
    return rr


def require_display(save_flag: str) -> None:
    """Raise a one-line `UserError` naming `save_flag` (the command's flag that saves an .rrd file
    instead) when the Rerun viewer cannot open a window: on Linux, neither DISPLAY nor
    WAYLAND_DISPLAY is set, and a spawned viewer would fail while the logging waits for it forever."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise UserError(
            f"the Rerun viewer needs a display and this session has none (neither DISPLAY nor WAYLAND_DISPLAY is set): "
            f"save a recording with {save_flag}=FILE.rrd and open it where there is a screen with `rerun FILE.rrd`"
        )


def open_recording(save: str | os.PathLike | None = None, save_flag: str = "--view_save"):
    """A Rerun recording stream: into the .rrd file `save`, else to a viewer (spawned if none runs;
    without a display, `require_display`'s error naming `save_flag`)."""
    rr = rerun()
    if save is None:
        require_display(save_flag)
    rec = rr.RecordingStream(APPLICATION_ID)
    if save is not None:
        rec.save(str(save))
    else:
        rec.spawn()
    return rec


@dataclasses.dataclass(frozen=True)
class Step:
    """What one step brought: the recorder has exactly this in hand at each step."""

    index: int
    time_s: float  # since the trial's first step
    windows: np.ndarray  # (2, 2048) int32 raw words of each microphone (internal, external)
    new_samples: int  # how many of the window's newest samples arrived since the previous step
    joints: np.ndarray  # (6, 3)
    force: float
    frame: np.ndarray | None = None  # (H, W, 3) uint8


def archive_step(trial: archive.TrialArchive, t: int) -> Step:
    """Step `t` of a recorded trial, as it came in."""
    new = archive.WINDOW if t == 0 else int(trial.window_end[t, 0] - trial.window_end[t - 1, 0])
    return Step(
        t,
        float(trial.timestamps[t] - trial.timestamps[0]),
        np.stack(live.step_windows(trial, t, [0, 1], [archive.WINDOW] * 2)),
        min(max(new, 0), archive.WINDOW),
        trial.joints[t],
        float(trial.force[t]),
        None if trial.images is None else trial.images[t],
    )


class TrialView:
    """Logs steps (and a model's results on them) to a Rerun recording stream `rec`."""

    def __init__(self, rec, label: int | None = None, meta: dict | None = None, reference: np.ndarray | None = None):
        import jax

        self.rr, self.rec, self.label, self.meta = (
            rerun(),
            rec,
            label,
            meta,
        )  # meta: the trial's, whose label map names the classes
        self.reference = reference  # (H, W, 3) uint8: the session's no-contact frame, None where the trial has none
        self.previous_frame, self.decided = None, False
        self.spectrogram = np.full((len(archive.MIC_NAMES), welch.N_BINS, SPECTROGRAM_STEPS), np.nan, np.float32)
        self.psd = jax.jit(lambda w: welch.welch_psd(w, bandwidth_khz=archive.NYQUIST_KHZ))

    def warmup(self, image_size: tuple[int, int] | None) -> None:
        """Compile the PSD and, for frames of `image_size` (H, W), the flow pooling, so that the
        first steps of a live trial are not held up by compilation."""
        self.psd(np.zeros((len(archive.MIC_NAMES), archive.WINDOW), np.int32)).block_until_ready()
        if image_size is not None:
            flow.sparsify_and_pool(np.zeros((1, *image_size, 2), np.float32)).block_until_ready()

    def _at(self, step: int, time_s: float) -> None:
        self.rec.set_time("step", sequence=step)
        self.rec.set_time("time", duration=time_s)

    def log_step(self, s: Step) -> None:
        rr, rec = self.rr, self.rec
        self._at(s.index, s.time_s)
        if s.frame is not None:
            rec.log("minsight/frame", rr.Image(s.frame))
            if self.reference is not None:
                if self.previous_frame is None:
                    rec.log("minsight/reference", rr.Image(self.reference))
                difference = s.frame.astype(np.int16) - self.reference
                rec.log("minsight/difference", rr.Image(np.clip(128 + difference, 0, 255).astype(np.uint8)))
            dense = flow.farneback(s.frame[None], self.previous_frame)
            rec.log("minsight/flow", rr.Image(false_colour.flow_rgb(np.asarray(flow.sparsify_and_pool(dense))[0])))
            self.previous_frame = s.frame
        psd = np.asarray(self.psd(s.windows))
        self.spectrogram = np.roll(self.spectrogram, -1, axis=2)
        self.spectrogram[:, :, -1] = psd
        sample_times = s.time_s - np.arange(s.new_samples)[::-1] / archive.AUDIO_RATE
        for i, mic in enumerate(archive.MIC_NAMES):
            rec.log(f"audio/{mic}/spectrogram", rr.Image(false_colour.magma_rgb(self.spectrogram[i, ::-1])))
            wave = np.asarray(welch.to_full_scale(s.windows[i, archive.WINDOW - s.new_samples :]), np.float64)
            rec.send_columns(
                f"audio/{mic}/wave",
                indexes=[rr.TimeColumn("time", duration=sample_times)],
                columns=rr.Scalars.columns(scalars=wave),
            )
        for j, joint in enumerate(archive.JOINT_NAMES):
            for k, field in enumerate(archive.JOINT_FIELDS):
                rec.log(f"joints/{joint}/{field}", rr.Scalars(float(s.joints[j, k])))
        rec.log("force", rr.Scalars(s.force))

    def log_prediction(self, r: live.StepResult) -> None:
        rr, rec = self.rr, self.rec
        self._at(r.step, r.time_s)
        rec.log("prediction/latency_ms", rr.Scalars(r.latency_ms))
        if r.probs is None:
            return
        k = int(np.argmax(r.probs))
        rec.log("prediction/probabilities", rr.BarChart(np.asarray(r.probs, np.float32)))
        rec.log("prediction/confidence", rr.Scalars(float(r.probs[k])))
        mark = "" if self.label is None else (" (correct)" if k == self.label else " (wrong)")
        rec.log("prediction/class", rr.TextLog(f"{live.class_name(k, self.meta)} p={r.probs[k]:.2f}{mark}"))
        if r.posterior is not None:  # the sequential rule's evidence over the windows so far
            j = int(np.argmax(r.posterior))
            rec.log("prediction/posterior", rr.Scalars(float(r.posterior[j])))
            if r.decided and not self.decided:
                rec.log(
                    "prediction/decision",
                    rr.TextLog(
                        f"decided: {live.class_name(j, self.meta)} posterior {r.posterior[j]:.3f} after "
                        f"{r.windows} windows"
                    ),
                )
            self.decided = r.decided


def log_trial(rec, trial: archive.TrialArchive, streamer: live.Streamer | None = None) -> dict[str, Any]:
    """Log a recorded trial, and `streamer`'s predictions over it (as fast as it runs); returns the
    streaming summary (`live.replay`), or {} without a model."""
    reference = None if trial.reference is None else np.rint(trial.reference.mean(0)).astype(np.uint8)
    view = TrialView(rec, int(trial.meta["label"]), trial.meta, reference)
    for t in range(trial.n_steps):
        view.log_step(archive_step(trial, t))
    if streamer is None:
        return {}
    return live.replay(streamer, trial, realtime=False, on_step=view.log_prediction)


def view_archive(path, *, checkpoint=None, save=None) -> dict[str, Any]:
    """`experiments.view`: one trial archive (frames included when recorded), with a streamable
    checkpoint's predictions over it, to `save` (.rrd) or a viewer."""
    if save is None:
        require_display("--save")
    trial = archive.read_archive(path, images=True)
    lay = archive.layout(trial.meta)
    if (
        lay.mics != live.HAND.mics
        or (lay.joint_names, lay.joint_fields) != (live.HAND.joint_names, live.HAND.joint_fields)
        or not lay.force
    ):
        raise UserError(
            f"{path}: meta.streams: the viewer shows the hand's streams ({live.HAND.describe()}); this trial "
            f"has {lay.describe()}"
        )
    streamer = None
    if checkpoint is not None:
        streamer = live.Streamer(*live.restore_model(checkpoint), layout=archive.layout(trial.meta))
    rec = open_recording(save, save_flag="--save")
    summary = log_trial(rec, trial, streamer)
    rec.flush()
    return {
        "archive": str(path),
        "steps": trial.n_steps,
        "frames": trial.images is not None,
        "rrd": None if save is None else str(save),
        **summary,
    }
