"""The air paths from the contacts to the palm microphone: what the fingertips and the cloth radiate.

[paper: the palm microphone "records environment noise"; palm audio alone classifies far worse
than Minsound] The palm SPH0645 is in free air ~8 cm from the pinch. It hears three small radiators
(positions and sources in calibration, "air paths"):
* each fingertip, a pulsating sphere: incompressible silicone makes the shell's outer volume change
  equal to its cavity's, so the radiated pressure follows the cavity pressure (rising 12 dB per
  octave below k a = 1). The thumb's contact is Minsound's; the middle finger's Minsight shell rubs
  the other face of the fold, an independent patch of the same cloth;
* the cloth in the pinch, an unbaffled disc of the contact's size moved by half of the difference
  of the two skins' mean displacements, a dipole (rising 18 dB per octave for a given displacement).
Each path carries its propagation delay r / c. A contact's spectrum is given as the equivalent
Minsound cavity pressure (`texture.vibration`, `stick_slip.spectrum`), before the shell.
"""

from __future__ import annotations

import numpy as np

from fabricjax.sim import calibration as cal


def distance_m(a, b) -> float:
    return float(np.linalg.norm(np.subtract(a, b)))


def delay(f: np.ndarray, r_m: float) -> np.ndarray:
    """exp(-j k r): the propagation phase over `r_m` metres (in single precision: phase errors of ~1e-6 rad)."""
    phase = (f * (-2 * np.pi * r_m / cal.SOUND_SPEED_M_S)).astype(np.float32)
    return np.cos(phase) + 1j * np.sin(phase)


def fingertip_radiation(f: np.ndarray, r_m: float) -> np.ndarray:
    """Pressure at `r_m` per cavity pressure of a fingertip radiating as a pulsating sphere, without the delay.

    [cited] The shell's outer volume changes by the cavity's dV = p V / (gamma P0); a sphere of radius a
    (half the shell's width) with that volume displacement radiates p(r) = -rho w^2 dV / (4 pi r (1 + j k a))
    (Kinsler et al., pulsating sphere); with rho c^2 = gamma P0: p / p_cavity = -k^2 V / (4 pi r (1 + j k a)).
    """
    k = 2 * np.pi * np.asarray(f, float) / cal.SOUND_SPEED_M_S
    a = cal.SHELL_WIDTH_MM / 2 * 1e-3
    return -(k**2) * cal.CAVITY_VOLUME_M3 / (4 * np.pi * r_m * (1 + 1j * k * a))


def cloth_radiation(f: np.ndarray, r_m: float, cos_theta: float) -> np.ndarray:
    """Pressure at `r_m` per cavity-equivalent contact pressure of the cloth's dipole, without the delay.

    [estimate] Only the contact's area-mean motion radiates: relief far shorter than the patch averages out,
    and its mean is what changes the cavity's volume, dV = p V / (gamma P0) over the patch area. The sheet
    moves by `CLOTH_DISPLACEMENT_SHARE` of the skins' mean displacement dV / A; an unbaffled disc of
    radius a moving by xi radiates p = -j rho c^2 k^3 (2 a^3 / (3 pi)) xi cos(theta) / r (Lamb's added
    mass 8 rho a^3 / 3 as a dipole).
    """
    k = 2 * np.pi * np.asarray(f, float) / cal.SOUND_SPEED_M_S
    xi_per_pa = cal.CLOTH_DISPLACEMENT_SHARE * cal.CAVITY_VOLUME_M3 / (cal.GAMMA_P0_PA * cal.CONTACT_AREA_M2)
    strength = cal.AIR_DENSITY_KG_M3 * cal.SOUND_SPEED_M_S**2 * 2 * cal.CLOTH_RADIATOR_RADIUS_M**3 / (3 * np.pi)
    return -1j * strength * k**3 * xi_per_pa * cos_theta / r_m


def palm_transfers(f: np.ndarray, wall) -> dict[str, np.ndarray]:
    """Palm pressure per cavity-equivalent contact pressure, delays included, for each radiator:
    "thumb" and "middle" (the fingertips, through their shells' wall transfer `wall`, e.g.
    `shell.contact_transfer(f)`) and "cloth"."""
    r_thumb = distance_m(cal.PALM_MIC_M, cal.THUMB_TIP_M)
    r_middle = distance_m(cal.PALM_MIC_M, cal.MIDDLE_TIP_M)
    r_cloth = distance_m(cal.PALM_MIC_M, (0.0, 0.0, 0.0))
    cos_theta = abs(cal.PALM_MIC_M[0]) / r_cloth  # the cloth's normal is the pinch axis x
    return {
        "thumb": wall * fingertip_radiation(f, r_thumb) * delay(f, r_thumb),
        "middle": wall * fingertip_radiation(f, r_middle) * delay(f, r_middle),
        "cloth": cloth_radiation(f, r_cloth, cos_theta) * delay(f, r_cloth),
    }
