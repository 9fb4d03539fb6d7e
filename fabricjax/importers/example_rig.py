"""Recordings of a rig unlike the hand, written as its lab would hand them over, and the batch
import's benchmark on them (`python -m experiments.bench --only=import`).

The rig is the one issue 26 describes (a public dataset of another tactile sensor): one vibration
channel at 2.2 kHz (int16 WAV), a 7-joint arm at 100 Hz with angle, velocity and torque (plus a
column the rig file does not name, as real exports have), no camera, no palm microphone, string
labels, no recording days. The signals are placeholders, not a model of any sensor, but they
behave as a low-rate vibration sensor rubbed over a texture does (`vibration`): the class lives in
the spectral shape of a noisy vibration that changes within a trial, so the tests and the worked
example see what such a rig gives (a spectrum that varies from step to step in a short window and
is nearly steady in a long one), not a tone a single bin could read.
"""

from __future__ import annotations

import csv
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.io import wavfile

VIBRATION_RATE = 2200  # Hz
JOINT_RATE = 100  # Hz
N_JOINTS = 7
STEP_RATE = 50  # Hz, the declared step clock
RIG_TOML = f"""[steps]
rate = {STEP_RATE}

[[mics]]
name = "vibration"
file = "vibration.wav"
role = "internal"

[joints]
file = "joints.csv"
names = [{", ".join(f'"arm_{k}"' for k in range(N_JOINTS))}]
fields = ["angle", "velocity", "torque"]
units = ["rad", "rad/s", "N m"]
"""
EXTRA_COLUMN = "gripper_temperature"  # in every joints.csv, not in the rig file
# The placeholder vibration (`vibration`): classes' texture frequencies at full stroke speed, spread
# evenly over this band (below the 1.1 kHz Nyquist), ...
TEXTURE_BAND_HZ = (150.0, 900.0)
STROKE_RATE = 1.5  # Hz: strokes per second; the speed follows |sin|, from SLOWEST of full speed up
SLOWEST = 0.35
TEXTURE_BANDWIDTH_HZ = 40.0  # ... each a narrow band of noise this wide (not a tone) ...
SECOND_HARMONIC = 0.5  # ... with a weaker second harmonic (relative amplitude) ...
BACKGROUND = 0.08  # ... over broadband noise (full-scale RMS, unchanged by the stroke) ...
GAIN_DB = 6.0  # ... and each trial's level random within +-this (contact pressure), so the level is no cue


def texture_frequency(class_id: int, n_classes: int) -> float:
    """Hz at full stroke speed: the class's place in `TEXTURE_BAND_HZ`."""
    lo, hi = TEXTURE_BAND_HZ
    return lo + (hi - lo) * class_id / max(n_classes - 1, 1)


def vibration(class_id: int, n_classes: int, seconds: float, rng: np.random.Generator) -> np.ndarray:
    """A placeholder vibration channel (full-scale units) of a fingertip stroking a texture: its
    frequency is the class's texture frequency times the stroke speed, which varies within every
    stroke, a narrow band of noise with a second harmonic whose amplitude follows the speed, over
    broadband noise, at a random trial level."""
    t = np.arange(int(seconds * VIBRATION_RATE)) / VIBRATION_RATE
    speed = SLOWEST + (1 - SLOWEST) * np.abs(np.sin(np.pi * STROKE_RATE * t + rng.uniform(0, np.pi)))
    phase = 2 * np.pi * np.cumsum(texture_frequency(class_id, n_classes) * speed) / VIBRATION_RATE
    smooth = max(1, int(VIBRATION_RATE / TEXTURE_BANDWIDTH_HZ))  # a moving average: a complex envelope ~this band wide
    envelope = np.convolve(
        rng.normal(size=t.size) + 1j * rng.normal(size=t.size), np.ones(smooth) / np.sqrt(smooth), "same"
    )
    texture = np.real(
        envelope * (np.exp(1j * phase) + SECOND_HARMONIC * np.exp(2j * phase + 1j * rng.uniform(0, 2 * np.pi)))
    )
    x = 0.15 * speed * texture / np.sqrt(2) + BACKGROUND * rng.normal(size=t.size)
    return x * 10 ** (rng.uniform(-GAIN_DB, GAIN_DB) / 20)


def write_trial(folder: Path, class_id: int, seconds: float, rng: np.random.Generator, n_classes: int = 20) -> None:
    """One trial folder: vibration.wav and joints.csv."""
    folder.mkdir(parents=True, exist_ok=True)
    x = vibration(class_id, n_classes, seconds, rng)
    wavfile.write(
        folder / "vibration.wav", VIBRATION_RATE, np.round(np.clip(x, -1, 1 - 2**-15) * 2**15).astype(np.int16)
    )
    jt = np.arange(int(seconds * JOINT_RATE)) / JOINT_RATE
    angle = 0.2 * np.sin(2 * np.pi * 1.5 * jt[:, None] + np.arange(N_JOINTS)) + rng.normal(0, 0.01, (jt.size, N_JOINTS))
    velocity = np.gradient(angle, jt, axis=0)
    torque = (0.5 + 0.05 * class_id) * angle + rng.normal(0, 0.02, angle.shape)
    header = (
        ["time"] + [f"arm_{j}_{f}" for j in range(N_JOINTS) for f in ("angle", "velocity", "torque")] + [EXTRA_COLUMN]
    )
    values = np.stack([angle, velocity, torque], axis=2).reshape(jt.size, -1)
    with open(folder / "joints.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(np.column_stack([jt, values, np.full(jt.size, 31.5)]).round(6).tolist())


def write_recordings(
    root: Path,
    labels: list[str],
    trials_per_label: int,
    seconds: tuple[float, float] = (6.0, 8.0),
    splits: dict[int, str] | None = None,
    seed: int = 0,
) -> Path:
    """Trial folders under root/recordings, rig.toml and manifest.csv (path, label and, when
    `splits` maps a trial index to a split, a split column). Returns the manifest."""
    rng = np.random.default_rng(seed)
    root.mkdir(parents=True, exist_ok=True)
    (root / "rig.toml").write_text(RIG_TOML)
    rows = []
    for c, label in enumerate(labels):
        for k in range(trials_per_label):
            rel = f"recordings/{c:02d}_{k:03d}"
            write_trial(root / rel, c, float(rng.uniform(*seconds)), rng, len(labels))
            rows.append([rel, label, k] + ([splits[k]] if splits else []))
    with open(root / "manifest.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["path", "label", "trial"] + (["split"] if splits else []))
        w.writerows(rows)
    return root / "manifest.csv"


def bench_import(trials: int = 1000, seconds: tuple[float, float] = (6.0, 8.0), workers: int | None = None) -> dict:
    """Wall time of `batch.run` for `trials` recordings of 6-8 s (20 labels), in a
    temporary folder; writing the recordings is not timed."""
    from fabricjax.importers import batch

    labels = [f"material {k}" for k in range(20)]
    with tempfile.TemporaryDirectory() as tmp:
        manifest = write_recordings(Path(tmp) / "rig", labels, max(1, trials // len(labels)), seconds)
        t0 = time.perf_counter()
        summary = batch.run(
            manifest,
            Path(tmp) / "archives",
            rig=Path(tmp) / "rig" / "rig.toml",
            split="fraction:0.7,0.15,0.15",
            workers=workers,
            progress=False,
            say=lambda s: None,
        )
        wall = time.perf_counter() - t0
        mb_in = sum(p.stat().st_size for p in (Path(tmp) / "rig").rglob("*") if p.is_file()) / 1e6
    return {
        "trials": summary["trials"],
        "seconds_per_trial": list(seconds),
        "wall_s": wall,
        "ms_per_trial": 1e3 * wall / summary["trials"],
        "steps": summary["steps"],
        "input_mb": mb_in,
        "target_s": 180.0,
        "meets_target": wall <= 180.0,
        "rig": f"1 vibration channel at {VIBRATION_RATE} Hz, {N_JOINTS} joints x 3 at {JOINT_RATE} Hz, no camera",
    }
