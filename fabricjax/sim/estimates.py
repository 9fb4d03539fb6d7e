"""What the simulator cannot know: every estimated magnitude, with its declared range and why.

A magnitude of the simulator either has a published source (cited where `calibration` sets it),
or it is an estimate declared here: its value, the low and high ends of the range a physical
reason allows, that reason in one line, and what it drives. The simulator reads every estimate
from this registry (`calibration` sets its constants from `value`), and the sensitivity study
(`python -m experiments.sensitivity`) moves them within their ranges to measure what each
finding depends on. An estimate pinned by one measurement of the paper says so in `calibrated`:
its value is then fitted to that measurement (`experiments.calibrate`), and that number of ours
is a calibration, no longer a finding.

Groups are the sensitivity study's factors: the estimates of one group act on one mechanism and
move together (each to the same relative place in its own range).
"""

from __future__ import annotations

import dataclasses
import math
from types import MappingProxyType
from typing import Mapping

STREAMS = ("audio", "proprio", "images")


@dataclasses.dataclass(frozen=True)
class Calibrated:
    """The one measurement of the paper an estimate is fitted to."""

    measurement: str  # what the paper measured
    paper_value: float
    where: str  # where the paper gives it
    fitted_on: str  # which of our numbers is matched to it
    study: str  # the study whose table holds that number (its other numbers are predictions)


@dataclasses.dataclass(frozen=True)
class Estimate:
    name: str  # the `calibration` constant it sets
    value: float
    low: float
    high: float
    reason: str  # one line: why the range is what it is
    drives: str  # what it changes in the data
    group: str  # the sensitivity study's factor it moves with
    streams: tuple[str, ...]  # what it touches: only these need simulating again when it moves
    log: bool = False  # the range spans orders of magnitude: moved on a log scale
    calibrated: Calibrated | None = None

    def __post_init__(self):
        if not self.low <= self.value <= self.high or self.low == self.high:
            raise ValueError(f"estimate {self.name}: value {self.value} outside its range [{self.low}, {self.high}]")
        if self.log and self.low <= 0:
            raise ValueError(f"estimate {self.name}: a log-scale range needs low > 0")
        if not set(self.streams) <= set(STREAMS) or not self.streams:
            raise ValueError(f"estimate {self.name}: streams must be some of {STREAMS}")

    def at(self, u: float) -> float:
        """The value at relative place `u` in [0, 1] of the range (log-spaced for a `log` range)."""
        if self.log:
            v = math.exp(math.log(self.low) + u * (math.log(self.high) - math.log(self.low)))
        else:
            v = self.low + u * (self.high - self.low)
        return float(min(max(v, self.low), self.high))  # rounding must not leave the range

    def place(self) -> float:
        """Where `value` sits in the range, in [0, 1] (the inverse of `at`)."""
        if self.log:
            return (math.log(self.value) - math.log(self.low)) / (math.log(self.high) - math.log(self.low))
        return (self.value - self.low) / (self.high - self.low)


_AUDIO, _ALL, _IMAGES = ("audio",), STREAMS, ("images",)

ESTIMATES: Mapping[str, Estimate] = MappingProxyType({e.name: e for e in (
    # --- the shell's airborne path: what room sound reaches Minsound ---------------------------
    Estimate(
        "SHELL_TL_MIN_DB", 3.0, 0.0, 10.0,
        "a sealed soft wall cannot block below its stiffness-controlled region; leaks at the base pass what the mass law would stop",
        "the room sound Minsound hears at low frequency (lab floor, cafe babble)", "shell airborne", _AUDIO),
    Estimate(
        "SHELL_TL_MAX_DB", 6.0, 6.0, 40.0,
        "flanking through the rigid skeleton and the seam at the base caps any wall's loss; 40 dB is a sealed enclosure's, 6 dB an open seam's",
        "how much room sound Minsound hears above ~300 Hz: the cafe's cost to Minsound", "shell airborne", _AUDIO,
        calibrated=Calibrated(
            "Minsound's drop from the lab test day (95.06 %) to the cafe (67.51 %)", 95.06 - 67.51,
            "Table ablation (Minsound alone, 95.06 %) and Table new_noise_results (Minsound, cafe, 67.51 %)",
            "the noise study's Minsound row: lab test minus cafe accuracy, mean of its 10 seeds, default preset", "noise")),
    # --- servo noise ----------------------------------------------------------------------------
    Estimate(
        "SERVO_TONE_PA", 0.006, 0.0015, 0.024, "micro-servo gear mesh heard through a skeleton: tens of dB, unmeasured for the STS3215",
        "the gear-mesh tone at both microphones, in every class", "servo noise", _AUDIO, log=True),
    Estimate(
        "SERVO_BROADBAND_PA", 0.004, 0.001, 0.016, "motor and gear broadband noise of a small servo: the tone's order, unmeasured",
        "the servos' broadband floor at both microphones", "servo noise", _AUDIO, log=True),
    Estimate(
        "SERVO_HOLD_PA", 0.001, 0.00025, 0.004, "PWM hum of holding servos: well below the moving gears' noise",
        "the always-present hum under every trial", "servo noise", _AUDIO, log=True),
    Estimate(
        "SERVO_PALM_GAIN_DB", -10.0, -20.0, 0.0, "the servos sit in the palm: airborne there at most as loud as structure-borne in the fingertip",
        "the servo noise the palm microphone hears", "servo noise", _AUDIO),
    # --- the cafe's sound besides its level -------------------------------------------------------
    Estimate(
        "CLATTER_PER_S", 1.5, 0.3, 6.0, "a quiet to a busy cafe: one clink every few seconds to several a second",
        "transients in the cafe condition", "cafe scene", _AUDIO, log=True),
    Estimate(
        "CLATTER_PEAK_DB", 12.0, 5.0, 20.0, "dish-handling peaks sit 5-10 dB and more above the meter's average (kitchen measurement)",
        "how loud the cafe's transients are", "cafe scene", _AUDIO),
    Estimate(
        "BABBLE_MODULATION", 0.25, 0.1, 0.6, "the envelope of N talkers fluctuates as 1/sqrt(N): 3 to 100 talkers",
        "the babble's syllabic rhythm", "cafe scene", _AUDIO),
    # --- the contact sound's size in Minsound ----------------------------------------------------
    Estimate(
        "WALL_COUPLING", 0.01, 0.003, 0.03, "a 3 mm silicone wall over a 5 mm patch passes a few per cent of the skin's displacement to its inner face",
        "the texture sound's level in Minsound against its noise", "contact sound", _AUDIO, log=True),
    Estimate(
        "SLIP_PA", 0.06, 0.02, 0.18, "asperity-scale releases of mu F_n: order-of-magnitude energy, unmeasured for this skin",
        "stick-slip clicks in Minsound", "contact sound", _AUDIO, log=True),
    Estimate(
        "RELEASE_PA", 0.15, 0.05, 0.45, "the stroke reversal's stored elastic energy: order of magnitude",
        "the release at every stroke reversal", "contact sound", _AUDIO, log=True),
    # --- the camera's day ---------------------------------------------------------------------
    Estimate(
        "SEATING_AXIAL_SD_MM", 0.05, 0.01, 0.1, "SLA-printed mating parts fit to ~0.1 mm: a remounted shell sits within a fraction of it",
        "where the shell sits on the camera each day: the frame's day term", "camera day", _IMAGES),
    Estimate(
        "FLAKE_CONTRAST", 0.5, 0.2, 1.0, "half the light from diffuse powder, the flakes' share varying with up to unit coefficient of variation",
        "the interior's grain, which a seating shift moves under every pixel", "camera day", _IMAGES),
    Estimate(
        "CAMERA_FULL_WELL_E", 6000.0, 3000.0, 12000.0, "the full well of 1.4-2 um CMOS pixels",
        "the camera's shot noise", "camera day", _IMAGES, log=True),
    # --- what the contact does to Minsight's wall ---------------------------------------------------
    Estimate(
        "SHELL_SHEAR_STIFFNESS_N_MM", 0.30, 0.1, 0.9, "a soft silicone shell's tangential stiffness at a 2 mm patch: of the order of its normal stiffness",
        "the shell's shear drag in the frames and the stick length of every stroke", "contact on Minsight", _ALL, log=True),
    Estimate(
        "CONTACT_OFFSET_MM", 1.5, 0.5, 3.0, "a force-controlled grasp is not placed: the patch wanders by a tenth to half of its ~5 mm size",
        "where the contact lands in the frame from trial to trial", "contact on Minsight", _IMAGES),
    Estimate(
        "CONFORM_PER_MM", 0.15, 0.05, 0.4, "a compressible stack spreads the load over a larger patch: tens of per cent per mm",
        "how the patch's size follows the fabric's thickness", "contact on Minsight", _IMAGES),
    # --- effects the published simulator leaves out (value 0), bounded by physics ------------------
    Estimate(
        "CONTACT_SHIFT_PER_STACK_MM", 0.0, 0.0, 0.2,
        "closing on arcs, a stack thicker by t turns the contact along the shell by R t / 2L: 0.1-0.2 mm per mm for L 60-30 mm; 0 leaves it out",
        "where the contact lands in the frame with the fabric's thickness (up to ~1 mm, a few pixels at 60x80)", "camera effects left out", _IMAGES),
)})

GROUPS: tuple[str, ...] = tuple(dict.fromkeys(e.group for e in ESTIMATES.values()))


_overrides: dict[str, float] = {}  # set by `override`: the values in force instead of the registry's


def value(name: str) -> float:
    """The value of estimate `name` in force: the registry's, unless `override` set another."""
    return _overrides.get(name, ESTIMATES[name].value)


def in_force() -> tuple[tuple[str, float], ...]:
    """The overrides in force (`override`), as `Scene.estimates` carries them: sorted pairs."""
    return tuple(sorted(_overrides.items()))


def override(values: Mapping[str, float]) -> None:
    """Put `values` (estimate name -> value, each within its range) in force instead of the
    registry's, and every other estimate back to the registry's value. Modules read estimates
    when they are executed: `trial.use_estimates` executes `calibration` again after this."""
    checked = check(values)
    _overrides.clear()
    _overrides.update(checked)


def calibrated_in(study: str) -> list[dict]:
    """The calibrations matched to a number of `study`'s table, as its results record them."""
    return [{"estimate": e.name, "value": e.value, "measurement": e.calibrated.measurement, "fitted_on": e.calibrated.fitted_on}
            for e in ESTIMATES.values() if e.calibrated is not None and e.calibrated.study == study]


def check(overrides: Mapping[str, float]) -> dict[str, float]:
    """`overrides` (estimate name -> value) as floats, each a registry name within its range."""
    out = {}
    for name, v in overrides.items():
        if name not in ESTIMATES:
            raise ValueError(f"unknown estimate {name!r}; known: {sorted(ESTIMATES)}")
        e = ESTIMATES[name]
        if not e.low <= v <= e.high:
            raise ValueError(f"estimate {name}={v} is outside its declared range [{e.low}, {e.high}]")
        out[name] = float(v)
    return out


def streams_touched(names) -> set[str]:
    """The streams the estimates `names` act on."""
    return {s for n in names for s in ESTIMATES[n].streams}
