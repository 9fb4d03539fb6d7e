"""The air path from the contact to the palm microphone: far weaker contact sound.

[paper: the palm microphone "records environment noise"; palm audio alone classifies far worse
than Minsound] The palm SPH0645 is in free air ~8 cm from the fingertips. It hears what the cloth
and fingertips radiate: a small radiator is inefficient below its corner frequency (pressure ~ f,
a monopole driven by volume acceleration) and the free-field pressure a few cm away is tens of dB
below the pressure in the closed Minsound cavity.
"""

from __future__ import annotations

import numpy as np

from fabricjax.sim import calibration as cal


def contact_transfer(f: np.ndarray) -> np.ndarray:
    s = 1j * f / cal.AIR_PATH_CORNER_HZ
    return 10 ** (cal.AIR_PATH_GAIN_DB / 20) * s / (1.0 + s)
