"""Recordings of a rig unlike the hand, written as its lab would hand them over, and the batch
import's benchmark on them (`python -m experiments.bench --only=import`).

The rig is the one issue 26 describes (a public dataset of another tactile sensor): one vibration
channel at 2.2 kHz (int16 WAV), a 7-joint arm at 100 Hz with angle, velocity and torque (plus a
column the rig file does not name, as real exports have), no camera, no palm microphone, string
labels, no recording days. The signals are placeholders with a class-dependent tone, not a model
of any sensor: they exist to exercise and time the import, and to give a study something
learnable.
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


def write_trial(folder: Path, class_id: int, seconds: float, rng: np.random.Generator) -> None:
    """One trial folder: vibration.wav and joints.csv."""
    folder.mkdir(parents=True, exist_ok=True)
    t = np.arange(int(seconds * VIBRATION_RATE)) / VIBRATION_RATE
    tone = 0.3 * np.sin(2 * np.pi * (120 + 60 * class_id) * t + rng.uniform(0, 2 * np.pi))
    x = tone + 0.1 * rng.normal(size=t.size)
    wavfile.write(folder / "vibration.wav", VIBRATION_RATE, np.round(x * 2**14).astype(np.int16))
    jt = np.arange(int(seconds * JOINT_RATE)) / JOINT_RATE
    angle = 0.2 * np.sin(2 * np.pi * 1.5 * jt[:, None] + np.arange(N_JOINTS)) + rng.normal(0, 0.01, (jt.size, N_JOINTS))
    velocity = np.gradient(angle, jt, axis=0)
    torque = (0.5 + 0.05 * class_id) * angle + rng.normal(0, 0.02, angle.shape)
    header = ["time"] + [f"arm_{j}_{f}" for j in range(N_JOINTS) for f in ("angle", "velocity", "torque")] + [EXTRA_COLUMN]
    values = np.stack([angle, velocity, torque], axis=2).reshape(jt.size, -1)
    with open(folder / "joints.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(np.column_stack([jt, values, np.full(jt.size, 31.5)]).round(6).tolist())


def write_recordings(root: Path, labels: list[str], trials_per_label: int, seconds: tuple[float, float] = (6.0, 8.0),
                     splits: dict[int, str] | None = None, seed: int = 0) -> Path:
    """Trial folders under root/recordings, rig.toml and manifest.csv (path, label and, when
    `splits` maps a trial index to a split, a split column). Returns the manifest."""
    rng = np.random.default_rng(seed)
    root.mkdir(parents=True, exist_ok=True)
    (root / "rig.toml").write_text(RIG_TOML)
    rows = []
    for c, label in enumerate(labels):
        for k in range(trials_per_label):
            rel = f"recordings/{c:02d}_{k:03d}"
            write_trial(root / rel, c, float(rng.uniform(*seconds)), rng)
            rows.append([rel, label, k] + ([splits[k]] if splits else []))
    with open(root / "manifest.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["path", "label", "trial"] + (["split"] if splits else []))
        w.writerows(rows)
    return root / "manifest.csv"


def bench_import(trials: int = 1000, seconds: tuple[float, float] = (6.0, 8.0), workers: int | None = None) -> dict:
    """Wall time of `import_manifest.run` for `trials` recordings of 6-8 s (20 labels), in a
    temporary folder; writing the recordings is not timed."""
    from acquisition import import_manifest

    labels = [f"material {k}" for k in range(20)]
    with tempfile.TemporaryDirectory() as tmp:
        manifest = write_recordings(Path(tmp) / "rig", labels, max(1, trials // len(labels)), seconds)
        t0 = time.perf_counter()
        summary = import_manifest.run(manifest, Path(tmp) / "archives", rig=Path(tmp) / "rig" / "rig.toml",
                                      split="fraction:0.7,0.15,0.15", workers=workers, progress=False, say=lambda s: None)
        wall = time.perf_counter() - t0
        mb_in = sum(p.stat().st_size for p in (Path(tmp) / "rig").rglob("*") if p.is_file()) / 1e6
    return {"trials": summary["trials"], "seconds_per_trial": list(seconds), "wall_s": wall, "ms_per_trial": 1e3 * wall / summary["trials"],
            "steps": summary["steps"], "input_mb": mb_in, "target_s": 180.0, "meets_target": wall <= 180.0,
            "rig": f"1 vibration channel at {VIBRATION_RATE} Hz, {N_JOINTS} joints x 3 at {JOINT_RATE} Hz, no camera"}
