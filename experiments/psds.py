"""Mean Minsound PSD per class plus the cafe noise as Minsound hears it (the paper's Fig. psds).

    python -m experiments.psds [--preset=default] [--workdir=DIR] [--results=DIR]

One trial per class (day 1, trial 0, lab) of the preset is simulated exactly as in its dataset
(same scenes and seeds, so the audio is bit-identical to the archives); the PSD is Welch's over
each step's 2048-sample window (scipy.signal.welch with `welch.SCIPY_KWARGS`: 512 bins), averaged over the
trial. The black curve is a minute of cafe noise recorded by Minsound with the hand at rest.
The legend names each class by its fabric (`plots.class_label`), as the other figures do.
"""

from __future__ import annotations

import numpy as np
import scipy.signal
from absl import flags as absl_flags

from experiments import flags
from fabricjax import catalog, presets
from fabricjax.features import welch
from fabricjax.reporting import plots
from fabricjax.sim import Scene, scene_for, simulate
from fabricjax.store import archive

FLAGS = absl_flags.FLAGS
flags.define_preset()


def mean_psd(audio_row: np.ndarray, window_end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (Hz) and the mean Welch PSD (full scale^2 / Hz) over the steps' windows."""
    x = np.asarray(welch.to_full_scale(audio_row), np.float64)  # exact: 18-bit samples / 2**17
    windows = np.stack([x[e - archive.WINDOW : e] for e in window_end])
    f, p = scipy.signal.welch(windows, axis=-1, **welch.SCIPY_KWARGS)
    return f, p.mean(axis=0)


def class_psds(preset_name: str) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    dataset = presets.get(preset_name).dataset
    specs = [
        s
        for s in dataset.trials()
        if s.day == dataset.splits.train_days[0] and s.trial == 0 and s.fabric_id < catalog.N_CLASSES
    ]
    psds = {}
    for spec in sorted(specs, key=lambda s: s.fabric_id):
        arch = simulate(scene_for(spec, dataset, ("audio", "proprio")))
        f, psds[plots.class_label(spec.fabric_id)] = mean_psd(arch.audio[0], arch.window_end[:, 0])
    cafe_day = dataset.splits.cafe_days[0]
    noise = simulate(Scene(0, day=cafe_day, condition="cafe", effects=("ambient", "shell", "sph0645"), cycles=120))
    return f, psds, mean_psd(noise.audio[0], noise.window_end[:, 0])[1]


def main(argv):
    del argv
    f, psds, noise = class_psds(FLAGS.preset)
    plots.plot_psds(flags.results_dir() / "psds.png", f, psds, noise=noise)  # listed by flags.run


if __name__ == "__main__":
    flags.run(main)
