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


def fingertip_radiation(f: np.ndarray) -> np.ndarray:
    """Palm pressure per Minsound cavity pressure radiated by the fingertip itself (not simulated:
    the lumped `contact_transfer` covers fingertip and cloth together and must exceed this).

    [phys] Silicone is incompressible (Poisson ratio ~0.5), so the shell's outer surface changes
    volume by exactly the cavity's dV: the fingertip is a pulsating sphere of radius a (half the
    shell's width) with volume velocity j w dV, whose pressure at r is j w rho dV' / (4 pi r (1 + j k a))
    (Kinsler & Frey, pulsating sphere). With the cavity's p = gamma P0 dV / V and c^2 = gamma P0 / rho:
    p_palm / p_cavity = -k^2 V / (4 pi r (1 + j k a)); -52 dB at 1 kHz, rising 12 dB per octave up
    to k a ~ 1 (3.6 kHz), 6 dB above.
    """
    k = 2 * np.pi * np.asarray(f, float) / cal.SOUND_SPEED_M_S
    a = cal.SHELL_WIDTH_MM / 2 * 1e-3
    return -(k**2) * cal.CAVITY_VOLUME_M3 / (4 * np.pi * cal.PALM_DISTANCE_M * (1 + 1j * k * a))

