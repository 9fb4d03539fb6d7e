"""The rig between sessions: the room's climate, what it does to friction and to the silicone, and
the cloth's wear over its recording history.

* Climate (effect "climate"): each recording day draws the room's temperature and relative
  humidity (calibration: ASHRAE ranges). Friction follows T x RH (a soft, hygroscopic contact),
  the silicone shells' stiffness follows the absolute temperature (entropic rubber elasticity).
  A stiffer shell deforms less per newton, so Minsight's force map, which reads deformation,
  reads low and the force-controlled closing stops later.
* Wear (effect "wear"): every earlier trial on a fabric rubbed part of its strip; the loose-fibre
  density of a staple-fibre cloth grows with the rubs a spot has had (`Scene.history` trials
  before this one, each of `Scene.cycles` cycles).

Without an effect its factor is 1: the catalog's fabric at the calibration's nominal conditions.
"""

from __future__ import annotations

import math

import numpy as np

from fabricjax.sim import calibration as cal


def climate(rng: np.random.Generator) -> tuple[float, float]:
    """(temperature C, relative humidity %) of one recording day."""
    return float(rng.uniform(*cal.ROOM_TEMPERATURE_C)), float(rng.uniform(*cal.ROOM_HUMIDITY_PCT))


def _t_rh(temperature_c: float, humidity_pct: float) -> float:
    return 1.0 + cal.FRICTION_CLIMATE_B_PER_A * temperature_c * humidity_pct


def friction_scale(temperature_c: float, humidity_pct: float) -> float:
    """Friction relative to the catalog's, which holds at the centre of the room's climate."""
    ref = _t_rh(float(np.mean(cal.ROOM_TEMPERATURE_C)), float(np.mean(cal.ROOM_HUMIDITY_PCT)))
    return _t_rh(temperature_c, humidity_pct) / ref


def silicone_scale(temperature_c: float) -> float:
    """The shells' stiffness relative to nominal: proportional to the absolute temperature."""
    return (temperature_c + cal.CELSIUS_K) / cal.SILICONE_REFERENCE_K


def spot_share() -> float:
    """Share of the trials whose rubbed stretch (the contact patch's diameter plus a stroke) covers
    a given spot of the strip."""
    rubbed = 2 * 1e3 * math.sqrt(cal.CONTACT_AREA_M2 / math.pi) + 2 * cal.RUB_AMPLITUDE_MM  # diameter, m -> mm
    lo, hi = cal.GRASP_RANGE_MM
    return rubbed / (hi - lo + rubbed)


def fuzz_scale(history: int, cycles: int) -> float:
    """Loose-fibre density relative to the new cloth's after `history` earlier trials of `cycles`."""
    rubs = history * cycles * 2 * spot_share()
    return 1.0 + rubs / cal.WEAR_DOUBLING_RUBS
