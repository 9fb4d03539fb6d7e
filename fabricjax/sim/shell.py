"""The soft shell around Minsound: how contact vibration and outside sound reach the internal mic.

[paper, Hardware] The SPH0645 sits at the base of a closed, opaque silicone shell on an aluminium
skeleton. Two paths:
* contact: the skin displacement reaches the cavity through the wall, a mass-spring wall mode
  (`SHELL_MODE_HZ`, Q) with viscoelastic loss rising with frequency (silicone damping);
* airborne: outside sound must pass the wall; the mass law gives a transmission loss of
  20 log10(f m'') - 47 dB with m'' the wall's construction (silicone density x shell thickness),
  bounded below by leaks and above by flanking through the skeleton. Low frequencies (babble,
  125-250 Hz) get through far more easily than high ones.
"""

from __future__ import annotations

import numpy as np

from fabricjax.sim import acoustics
from fabricjax.sim import calibration as cal


def contact_transfer(f: np.ndarray) -> np.ndarray:
    return acoustics.resonance(f, cal.SHELL_MODE_HZ, cal.SHELL_MODE_Q) * np.exp(-f / cal.SHELL_LOSS_HZ)


def surface_mass_kg_m2() -> float:
    return cal.SILICONE_DENSITY_KG_M3 * cal.SHELL_THICKNESS_MM * 1e-3


def transmission_loss_db(f: np.ndarray) -> np.ndarray:
    tl = 20 * np.log10(np.maximum(f, 1.0) * surface_mass_kg_m2()) - cal.MASS_LAW_DB
    return np.clip(tl, cal.SHELL_TL_MIN_DB, cal.SHELL_TL_MAX_DB)


def airborne_transfer(f: np.ndarray) -> np.ndarray:
    return 10 ** (-transmission_loss_db(f) / 20)
