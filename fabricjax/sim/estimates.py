"""What the simulator cannot know: every estimated magnitude, with its declared range and why.

A magnitude of the simulator either has a published source (cited where `calibration` sets it),
or it is an estimate declared here: its value, the low and high ends of the range a physical
reason allows, that reason in one line, and what it drives. The simulator reads every estimate
from this registry (`calibration` holds each at the value in force), and the sensitivity study
(`python -m experiments.sensitivity`) moves them within their ranges to measure what each
finding depends on. An estimate pinned by one measurement of the paper says so in `calibrated`:
its value is then fitted to that measurement (`experiments.calibrate`), and that number of ours
is a calibration, no longer a finding.

Groups are the sensitivity study's factors: the estimates of one group act on one mechanism and
move together (each to the same relative place in its own range).

An estimate is a `calibration` constant of its own name (`constants`), declared here only: the
registry is the one place that names it. A tuple of `calibration` (a draw range, a position, a
joint pose) or a constant in other units has one estimate per element, which names that constant
in `element_of` and which `calibration` reads with `value` where it builds it
(`SPEAKER_DISTANCE_M` is `SPEAKER_DISTANCE_NEAR_M` to `SPEAKER_DISTANCE_FAR_M`), so the registry
holds scalars only. `markdown_table` renders the registry for docs/simulator.md
(`python -m experiments.estimates` writes it there); `tests/test_estimates.py` checks that every
number of `fabricjax.sim` is a registry estimate or carries its source tag (see `calibration`).
"""

from __future__ import annotations

import dataclasses
import hashlib
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
    name: str  # the `calibration` constant it is (unless `element_of`)
    value: float
    low: float
    high: float
    reason: str  # one line: why the range is what it is
    drives: str  # what it changes in the data
    group: str  # the sensitivity study's factor it moves with
    streams: tuple[str, ...]  # what it touches: only these need simulating again when it moves
    log: bool = False  # the range spans orders of magnitude: moved on a log scale
    calibrated: Calibrated | None = None
    element_of: str | None = None  # the `calibration` constant it is an element of, not one of its own

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


_AUDIO, _ALL, _IMAGES, _PROPRIO = ("audio",), STREAMS, ("images",), ("proprio",)
_AUDIO_PROPRIO = ("audio", "proprio")

ESTIMATES: Mapping[str, Estimate] = MappingProxyType(
    {
        e.name: e
        for e in (
            # --- the shell's airborne path: what room sound reaches Minsound ---------------------------
            Estimate(
                "SHELL_TL_MIN_DB",
                3.0,
                0.0,
                10.0,
                "a sealed soft wall cannot block below its stiffness-controlled region; leaks at the base "
                "pass what the mass law would stop",
                "the room sound Minsound hears at low frequency (lab floor, cafe babble)",
                "shell airborne",
                _AUDIO,
            ),
            Estimate(
                "SHELL_TL_MAX_DB",
                6.0,
                6.0,
                40.0,
                "flanking through the rigid skeleton and the seam at the base caps any wall's loss; 40 dB is "
                "a sealed enclosure's, 6 dB an open seam's",
                "how much room sound Minsound hears above ~300 Hz: the cafe's cost to Minsound",
                "shell airborne",
                _AUDIO,
                calibrated=Calibrated(
                    "Minsound's drop from the lab test day (95.06 %) to the cafe (67.51 %)",
                    95.06 - 67.51,
                    "Table ablation (Minsound alone, 95.06 %) and Table new_noise_results (Minsound, cafe, 67.51 %)",
                    "the noise study's Minsound row: lab test minus cafe accuracy, mean of its 10 seeds, "
                    "default preset",
                    "noise",
                ),
            ),
            # --- servo noise ----------------------------------------------------------------------------
            Estimate(
                "SERVO_TONE_PA",
                0.006,
                0.0015,
                0.024,
                "micro-servo gear mesh heard through a skeleton: tens of dB, unmeasured for the STS3215",
                "the gear-mesh tone at both microphones, in every class",
                "servo noise",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "SERVO_HARMONIC_2",
                0.5,
                0.2,
                1.0,
                "gear-mesh noise carries harmonics of the mesh frequency from tooth-profile errors, within "
                "some 0-14 dB of it; unmeasured for the STS3215",
                "the gear-mesh tone's second harmonic (amplitude relative to the first)",
                "servo noise",
                _AUDIO,
                log=True,
                element_of="SERVO_HARMONICS",
            ),
            Estimate(
                "SERVO_HARMONIC_3",
                0.25,
                0.08,
                0.6,
                "as the second harmonic, a few dB further down: -4 to -22 dB",
                "the gear-mesh tone's third harmonic (amplitude relative to the first)",
                "servo noise",
                _AUDIO,
                log=True,
                element_of="SERVO_HARMONICS",
            ),
            Estimate(
                "SERVO_BROADBAND_PA",
                0.004,
                0.001,
                0.016,
                "motor and gear broadband noise of a small servo: the tone's order, unmeasured",
                "the servos' broadband floor at both microphones",
                "servo noise",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "SERVO_HOLD_PA",
                0.001,
                0.00025,
                0.004,
                "PWM hum of holding servos: well below the moving gears' noise",
                "the always-present hum under every trial",
                "servo noise",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "SERVO_PALM_GAIN_DB",
                -10.0,
                -20.0,
                0.0,
                "the servos sit in the palm: airborne there at most as loud as structure-borne in the fingertip",
                "the servo noise the palm microphone hears",
                "servo noise",
                _AUDIO,
            ),
            Estimate(
                "GEAR_TEETH",
                10.0,
                6.0,
                16.0,
                "the first-stage pinion of a small servo motor has some 6-16 teeth; the STS3215's is unpublished",
                "the gear-mesh tone's frequency (motor rev/s x teeth)",
                "servo noise",
                _AUDIO,
            ),
            Estimate(
                "SERVO_LOAD_REF_NM",
                0.01,
                0.003,
                0.03,
                "gear noise grows with the transmitted torque; a 0.1 N pinch loads a joint with mN m: the "
                "doubling torque is of that order",
                "how much the contact's load raises the servo noise (its friction information)",
                "servo noise",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "SERVO_BAND_LOW_HZ",
                150.0,
                75.0,
                300.0,
                "the skeleton's mounting resonances pass little structure-borne sound below ~100-300 Hz",
                "the low edge of the servo noise inside Minsound and at the palm",
                "servo noise",
                _AUDIO,
                log=True,
                element_of="SERVO_STRUCTURE_BAND_HZ",
            ),
            Estimate(
                "SERVO_BAND_HIGH_HZ",
                6000.0,
                3000.0,
                12000.0,
                "silicone and the joints' contacts damp structure-borne sound above a few kHz",
                "the high edge of the servo noise inside Minsound",
                "servo noise",
                _AUDIO,
                log=True,
                element_of="SERVO_STRUCTURE_BAND_HZ",
            ),
            # --- the cafe's sound besides its level -------------------------------------------------------
            Estimate(
                "CLATTER_PER_S",
                1.5,
                0.3,
                6.0,
                "a quiet to a busy cafe: one clink every few seconds to several a second",
                "transients in the cafe condition",
                "cafe scene",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "CLATTER_PEAK_DB",
                12.0,
                5.0,
                20.0,
                "dish-handling peaks sit 5-10 dB and more above the meter's average (kitchen measurement)",
                "how loud the cafe's transients are",
                "cafe scene",
                _AUDIO,
            ),
            Estimate(
                "BABBLE_MODULATION",
                0.25,
                0.1,
                0.6,
                "the envelope of N talkers fluctuates as 1/sqrt(N): 3 to 100 talkers",
                "the babble's syllabic rhythm",
                "cafe scene",
                _AUDIO,
            ),
            Estimate(
                "CLATTER_RING_LOW_HZ",
                2000.0,
                1000.0,
                3000.0,
                "cups and plates ring from ~1 kHz up; the recording's tableware is unknown",
                "the lowest ring of the cafe's clatter",
                "cafe scene",
                _AUDIO,
                element_of="CLATTER_RING_HZ",
            ),
            Estimate(
                "CLATTER_RING_HIGH_HZ",
                7000.0,
                4000.0,
                12000.0,
                "cutlery and glass ring up to ~10 kHz and beyond",
                "the highest ring of the cafe's clatter",
                "cafe scene",
                _AUDIO,
                log=True,
                element_of="CLATTER_RING_HZ",
            ),
            Estimate(
                "CLATTER_DECAY_S",
                0.015,
                0.005,
                0.05,
                "tableware struck on a table rings down within tens of ms",
                "how long each clink rings",
                "cafe scene",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "CLATTER_DECAY_SPREAD",
                0.5,
                0.2,
                0.8,
                "cups, plates and cutlery ring down at different rates: the longest ring 1.5 to 9 times the "
                "shortest ((1 + x) / (1 - x))",
                "the spread of the clinks' ring times",
                "cafe scene",
                _AUDIO,
            ),
            Estimate(
                "CLATTER_LEVEL_SPREAD",
                0.5,
                0.2,
                1.0,
                "clinks differ in strength by a factor 1.2 to 2.7 (log-normal sigma), unmeasured",
                "the spread of the clinks' amplitudes",
                "cafe scene",
                _AUDIO,
            ),
            Estimate(
                "CAFE_DAY_SPREAD_DB",
                2.0,
                0.5,
                4.0,
                "the paper's 47-55 dB(A) spans its cafe days and trials together; their split is unmeasured",
                "how much of the cafe level's spread is the day's (the rest the trial's)",
                "cafe scene",
                _AUDIO,
            ),
            Estimate(
                "CAFE_TRIAL_JITTER_DB",
                1.0,
                0.3,
                2.0,
                "the paper's 47-55 dB(A) spans cafe days and trials together; a played recording's "
                "half-minute excerpts differ by tenths of a dB to a few dB",
                "the cafe level's change from trial to trial within a day",
                "cafe scene",
                _AUDIO,
            ),
            Estimate(
                "SPEAKER_DISTANCE_NEAR_M",
                0.5,
                0.3,
                1.0,
                "a loudspeaker on a table by the rig, unplaced by the paper: from arm's length",
                "the loudspeaker's nearest place: its direct sound against the room's at each microphone",
                "cafe scene",
                _AUDIO,
                element_of="SPEAKER_DISTANCE_M",
            ),
            Estimate(
                "SPEAKER_DISTANCE_FAR_M",
                2.0,
                1.0,
                4.0,
                "to across the bench or the room's near side",
                "the loudspeaker's farthest place",
                "cafe scene",
                _AUDIO,
                log=True,
                element_of="SPEAKER_DISTANCE_M",
            ),
            Estimate(
                "SPEAKER_Q",
                2.0,
                1.0,
                4.0,
                "a small closed box is omnidirectional (Q = 1) at low and beamed (Q ~ 4) at high frequency "
                "(Beranek, Acoustics, Ch. 4)",
                "the loudspeaker's direct sound against the reverberant",
                "cafe scene",
                _AUDIO,
                log=True,
            ),
            # --- the contact sound's size in Minsound and its paths to the palm -----------------------------
            Estimate(
                "WALL_COUPLING",
                0.01,
                0.003,
                0.03,
                "a 3 mm silicone wall over a 5 mm patch passes a few per cent of the skin's displacement to "
                "its inner face",
                "the texture sound's level in Minsound against its noise",
                "contact sound",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "SLIP_PA",
                0.06,
                0.02,
                0.18,
                "asperity-scale releases of mu F_n: order-of-magnitude energy, unmeasured for this skin",
                "stick-slip clicks in Minsound",
                "contact sound",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "RELEASE_PA",
                0.15,
                0.05,
                0.45,
                "the stroke reversal's stored elastic energy: order of magnitude",
                "the release at every stroke reversal",
                "contact sound",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "CONTACT_AREA_M2",
                20e-6,
                8e-6,
                40e-6,
                "Hertz at 0.1 N with Ecoflex 00-30's datasheet modulus gives a 3.6 mm disc (10 mm^2); a "
                "cloth stack conforms and spreads it",
                "the volume the contact displaces (texture level), the cloth's radiating disc, the rubbed "
                "share of the strip",
                "contact sound",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "CAVITY_VOLUME_M3",
                8e-6,
                3e-6,
                12e-6,
                "a fingertip of Minsight's size (10.25 mm radius, 15 mm cylinder and cap) holds ~7 cm^3, "
                "less its skeleton and board",
                "the cavity pressure per displaced volume (Minsound's contact sound)",
                "contact sound",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "SHELL_MODE_HZ",
                3000.0,
                1500.0,
                6000.0,
                "the silicone wall's mass on its own stiffness and the cavity's air spring: kHz order, unmeasured",
                "where the contact sound in Minsound peaks and starts to fall",
                "contact sound",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "SHELL_MODE_Q",
                1.5,
                0.7,
                4.0,
                "soft silicones' loss factors of ~0.2-1, and a wall loaded by the contact: a broad resonance",
                "how sharply the wall mode shapes the contact sound",
                "contact sound",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "SHELL_LOSS_HZ",
                12000.0,
                6000.0,
                24000.0,
                "silicone damping rises with frequency: one e-fold of extra loss somewhere in 6-24 kHz",
                "the contact sound's fall above the wall mode",
                "contact sound",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "SLIPS_PER_MM",
                6.0,
                2.0,
                18.0,
                "micro-slips at the spacing of fibres (tens of um) to yarns (~1 mm): a few to tens per mm "
                "slid at mu = 1",
                "how many stick-slip clicks a stroke makes",
                "contact sound",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "SLIP_RING_LOW_HZ",
                900.0,
                450.0,
                1800.0,
                "milligrams of skin on the contact's stiffness ring at kHz order: a factor 2 either way",
                "the clicks' ring on the softest contacts (thick, compressible stacks)",
                "contact sound",
                _AUDIO,
                log=True,
                element_of="SLIP_RING_HZ",
            ),
            Estimate(
                "SLIP_RING_HIGH_HZ",
                3500.0,
                1800.0,
                7000.0,
                "the same on the stiffest contact (no cloth): a factor 2 either way",
                "the clicks' ring on the stiffest contacts",
                "contact sound",
                _AUDIO,
                log=True,
                element_of="SLIP_RING_HZ",
            ),
            Estimate(
                "SLIP_RING_SPREAD",
                0.1,
                0.03,
                0.3,
                "the ring follows the skin's mass on the contact's stiffness, which vary with where the "
                "patch sits and how the stack lies: a few to tens of per cent",
                "the clicks' ring from trial to trial at one stiffness",
                "contact sound",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "SLIP_DECAY_S",
                0.0003,
                0.0001,
                0.001,
                "a heavily damped skin rings for a cycle or a few of its kHz ring",
                "how long each click rings",
                "contact sound",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "SLIP_SPREAD",
                0.5,
                0.2,
                1.0,
                "asperity heights and stick lengths vary between clicks by a factor 1.2 to 2.7 (log-normal sigma)",
                "the spread of the clicks' amplitudes",
                "contact sound",
                _AUDIO,
            ),
            Estimate(
                "FINGERTIP_OFFSET_M",
                0.015,
                0.012,
                0.018,
                "the shell's radius (11.8 mm [minsight]) plus half the stack puts a centre 12-14 mm from the "
                "pinch; 15 mm is the earlier width estimate",
                "the fingertips' distances to the palm microphone",
                "contact sound",
                _AUDIO,
                element_of="THUMB_TIP_M",
            ),
            Estimate(
                "PALM_MIC_X_M",
                -0.03,
                -0.05,
                -0.01,
                "'on the side of the palm' [paper], the ISyHand's dimensions unpublished: each coordinate "
                "within +-2 cm",
                "where the palm microphone sits along the pinch axis (thumb side)",
                "contact sound",
                _AUDIO,
                element_of="PALM_MIC_M",
            ),
            Estimate(
                "PALM_MIC_Y_M",
                -0.07,
                -0.09,
                -0.05,
                "as the other coordinates: ~8 cm from the pinch, within +-2 cm",
                "how far below the pinch the palm microphone sits",
                "contact sound",
                _AUDIO,
                element_of="PALM_MIC_M",
            ),
            Estimate(
                "PALM_MIC_Z_M",
                0.02,
                0.0,
                0.04,
                "as the other coordinates: within +-2 cm",
                "how far behind the pinch the palm microphone sits",
                "contact sound",
                _AUDIO,
                element_of="PALM_MIC_M",
            ),
            Estimate(
                "CLOTH_DISPLACEMENT_SHARE",
                0.5,
                0.3,
                0.7,
                "equal shells in series put the sheet midway; unequal shells or a compliant stack move it by "
                "tens of per cent",
                "the cloth's dipole at the palm microphone",
                "contact sound",
                _AUDIO,
            ),
            # --- the camera -----------------------------------------------------------------------------
            Estimate(
                "SEATING_AXIAL_SD_MM",
                0.05,
                0.01,
                0.1,
                "SLA-printed mating parts fit to ~0.1 mm: the over-moulded shell sits within a fraction of it",
                "where the shell sits on the camera (the device's, the same every day)",
                "camera day",
                _IMAGES,
            ),
            Estimate(
                "FLAKE_CONTRAST",
                0.5,
                0.2,
                1.0,
                "half the light from diffuse powder, the flakes' share varying with up to unit coefficient "
                "of variation",
                "the interior's grain, which a seating shift moves under every pixel",
                "camera day",
                _IMAGES,
            ),
            Estimate(
                "CAMERA_FULL_WELL_E",
                6000.0,
                3000.0,
                12000.0,
                "the full well of 1.4-2 um CMOS pixels",
                "the camera's shot noise",
                "camera day",
                _IMAGES,
                log=True,
            ),
            Estimate(
                "CAMERA_HALF_FOV_DEG",
                80.0,
                65.0,
                90.0,
                "the image must reach the wall near the base (80 deg off axis at ~1.8 mm above the camera); "
                "the lens is unpublished",
                "how much of the wall each frame sees, and at what scale",
                "camera day",
                _IMAGES,
                element_of="CAMERA_HALF_FOV_RAD",
            ),
            Estimate(
                "LED_RING_RADIUS_MM",
                6.0,
                4.0,
                8.5,
                "inside the 10.25 mm skeleton [minsight], outside the camera module",
                "the LEDs' angles of incidence: the shading a tilted wall makes",
                "camera day",
                _IMAGES,
            ),
            Estimate(
                "COLLIMATOR_HALF_ANGLE_DEG",
                75.0,
                60.0,
                88.0,
                "Minsight's reference is lit to the image circle's edge: from a ring LED the wall ~1.8 mm above "
                "the camera lies 67-84 deg off axis; the collimator's optics are unpublished",
                "where on the wall each LED's light ends: the colour zones' borders",
                "camera day",
                _IMAGES,
                element_of="COLLIMATOR_HALF_ANGLE_RAD",
            ),
            Estimate(
                "COLLIMATOR_EDGE_DEG",
                3.0,
                1.0,
                10.0,
                "the reference's colour zones meet at sharp edges: an aperture's penumbra of a few degrees",
                "how sharp the colour zones' borders are",
                "camera day",
                _IMAGES,
                log=True,
                element_of="COLLIMATOR_EDGE_RAD",
            ),
            Estimate(
                "INTERIOR_RIDGE_HEIGHT_MM",
                0.1,
                0.03,
                0.3,
                "the mould insert's ridges: a printed insert's relief of tenths of a millimetre, sharp lines "
                "in the reference image",
                "the interior's pattern, which every wall motion moves under the pixels",
                "camera day",
                _IMAGES,
                log=True,
            ),
            Estimate(
                "INTERIOR_REFLECTANCE",
                0.6,
                0.4,
                0.8,
                "aluminium-powder-filled silicone is a grey metallic diffuser: aluminium paints reflect 0.6-0.75, "
                "a filled elastomer less",
                "how evenly the interior is lit, and so the brightness of the wall away from the LEDs",
                "camera day",
                _IMAGES,
            ),
            Estimate(
                "USB_VBUS_DAY_SPREAD_V",
                0.03,
                0.01,
                0.1,
                "the USB 2.0 bound of +-0.25 V covers all hosts and loads; one port of one host moves by tens of mV",
                "the LEDs' light from day to day, most for red",
                "camera day",
                _IMAGES,
                log=True,
            ),
            Estimate(
                "EXPOSURE_LEVEL_DN",
                135.0,
                100.0,
                170.0,
                "Minsight's averaged reference reads ~135 DN in its side-wall band; the median of the whole "
                "circle within a quarter of that",
                "the frames' brightness, and with it the shot noise's share",
                "camera day",
                _IMAGES,
            ),
            # --- what the contact does to Minsight's wall ---------------------------------------------------
            Estimate(
                "SHELL_SHEAR_STIFFNESS_N_MM",
                0.30,
                0.1,
                0.9,
                "a soft silicone shell's tangential stiffness at a 2 mm patch: of the order of its normal stiffness",
                "the shell's shear drag in the frames and the stick length of every stroke",
                "contact on Minsight",
                _ALL,
                log=True,
            ),
            Estimate(
                "CONTACT_OFFSET_MM",
                1.5,
                0.5,
                3.0,
                "a force-controlled grasp is not placed: the patch wanders by a tenth to half of its ~5 mm size",
                "where the contact lands in the frame from trial to trial",
                "contact on Minsight",
                _IMAGES,
            ),
            Estimate(
                "INNER_FACE_FREE_GAIN",
                1.0,
                1.0,
                1.6,
                "between the skeleton's struts the inner face is free: it moves at least as the half-space at "
                "that depth (0.62 of the indentation) and at most with the outer surface",
                "how much of the contact's indentation and texture reaches the imaged wall",
                "contact on Minsight",
                _IMAGES,
            ),
            Estimate(
                "INNER_SHEAR_SHARE",
                0.62,
                0.34,
                1.0,
                "the skin's drag reaches the inner face between a bonded layer's e^(-kd) share at the patch's "
                "scale and all of it (a free face between struts)",
                "how far the wall's pattern moves with the shear: the frames' and optical flow's drag",
                "contact on Minsight",
                _IMAGES,
            ),
            Estimate(
                "SHELL_NORMAL_STIFFNESS_N_MM",
                0.25,
                0.15,
                0.4,
                "Hertz between two Ecoflex 00-30 shells (datasheet modulus) gives 0.19 N/mm secant, 0.28 "
                "tangent at 0.1 N; the skeleton stiffens it",
                "the closing travel, the grasp's overshoot and the load's swing over a stroke",
                "contact on Minsight",
                _ALL,
            ),
            Estimate(
                "BENDING_REF_STRETCH_N_MM",
                5.0,
                2.0,
                12.0,
                "the layer whose bending starts to widen the patch: a shirting cotton's in-plane stiffness, "
                "a few N/mm at 0.5 mm",
                "how much a stiff stack widens the patch across the fold",
                "contact on Minsight",
                _IMAGES,
                log=True,
            ),
            Estimate(
                "RIDGE_WAVELENGTH_PER_THICKNESS",
                4.0,
                2.0,
                8.0,
                "a ridge of width w has its relief at wavelengths of 2 w (a half-sine bump) to several w (a "
                "smooth crease)",
                "how much of the fold ridge thick stacks press through to the inner wall",
                "contact on Minsight",
                _IMAGES,
                log=True,
            ),
            Estimate(
                "FOLD_ANGLE_SPREAD_RAD",
                0.3,
                0.1,
                0.6,
                "a hand-hung fold's direction after the hanger moves: within ~5-35 degrees of the finger's axis",
                "the patch's orientation in the frame from trial to trial",
                "contact on Minsight",
                _IMAGES,
                log=True,
            ),
            # --- the procedure: finger motion, timing and the grasp ------------------------------------------
            Estimate(
                "FRAME_JITTER_S",
                0.0008,
                0.0002,
                0.002,
                "a UVC camera's frames timestamped on the host: a USB 2.0 microframe (125 us) to user-space "
                "wake-up latency (~1 ms)",
                "each frame's capture time, with it the audio window and joint reading it carries",
                "procedure",
                _ALL,
                log=True,
            ),
            Estimate(
                "OPEN_GAP_MM",
                14.0,
                9.0,
                25.0,
                "the open pose must clear the thickest folded stack (~6 mm) and stay within a human-sized pinch",
                "the closing time before contact: when the rubbing starts",
                "procedure",
                _ALL,
            ),
            Estimate(
                "CLOSING_SPEED_MM_S",
                20.0,
                10.0,
                40.0,
                "a closing checked once per 20 ms frame: slow enough to stop within ~0.5 mm of the "
                "threshold, fast enough to close in a second",
                "the grasp force's overshoot past 0.1 N, and the closing time",
                "procedure",
                _ALL,
                log=True,
            ),
            Estimate(
                "SETTLE_S",
                0.1,
                0.04,
                0.3,
                "a commanded pause between two motions: a few control periods to a few tenths of a second",
                "the pause between the grasp and the first stroke",
                "procedure",
                _ALL,
                log=True,
            ),
            Estimate(
                "STOP_S",
                0.1,
                0.04,
                0.3,
                "the recording stops a few control periods to a few tenths of a second after the last stroke",
                "the trial's still tail",
                "procedure",
                _ALL,
                log=True,
            ),
            Estimate(
                "RUB_AMPLITUDE_MM",
                3.0,
                1.5,
                6.0,
                "a stroke must exceed the 0.1-0.3 mm stick length many times over and stay on a ~20 mm fingertip pad",
                "the stroke's length: slide speed, texture frequencies, the joints' swing",
                "procedure",
                _ALL,
                log=True,
            ),
            Estimate(
                "RUB_RAMP_CYCLES",
                0.25,
                0.1,
                0.5,
                "a servo starting a preprogrammed stroke from rest reaches its amplitude within a tenth to "
                "half a cycle (its acceleration limit); unpublished",
                "the first stroke's run-up: its slide speed and joint swing",
                "procedure",
                _ALL,
                log=True,
            ),
            Estimate(
                "CYCLE_HZ",
                2.0,
                1.7,
                2.4,
                "the paper's ~1500 steps (30 s) per 50-cycle trial, with the closing and the load's droop, "
                "bound the commanded rate",
                "the rubbing rate: trial length, slide speed, texture frequencies",
                "procedure",
                _ALL,
            ),
            Estimate(
                "ARC_MM",
                0.15,
                0.05,
                0.4,
                "the sagitta of two fingertips' +-3 mm arcs on 60 mm levers is 0.15 mm; the other joints and "
                "the pad's curvature change it",
                "the normal force's swing at the stroke ends",
                "procedure",
                _ALL,
                log=True,
            ),
            Estimate(
                "SPEED_DROOP_PER_N",
                2.0,
                0.7,
                5.0,
                "position-controlled servos lose a few to ~40 % of their speed at these loads; the paper: "
                "slower on high friction",
                "how trial length follows friction",
                "procedure",
                _ALL,
                log=True,
            ),
            Estimate(
                "SPEED_JITTER",
                0.02,
                0.006,
                0.05,
                "the STS3215's speed moves ~6 %/V (datasheet speeds at 7.4 and 12 V); a supply sags by "
                "0.1-0.5 V under load",
                "the rubbing rate's spread between trials",
                "procedure",
                _ALL,
                log=True,
            ),
            Estimate(
                "CYCLE_PHASE_JITTER",
                0.01,
                0.003,
                0.03,
                "the stroke rate's wander within a trial: below the spread between trials, from the same "
                "supply and load",
                "the stroke rate's wander within a trial",
                "procedure",
                _ALL,
                log=True,
            ),
            Estimate(
                "CYCLE_WANDER_S",
                0.1,
                0.03,
                0.5,
                "the supply's and the load's fluctuations change over a servo's control periods (tens of ms) "
                "to a stroke (0.5 s)",
                "how fast the stroke rate wanders within a trial",
                "procedure",
                _ALL,
                log=True,
            ),
            Estimate(
                "FOLD_SPREAD",
                0.1,
                0.03,
                0.25,
                "a hand-folded stack: two layers plus slack and seams, a few to 25 % off its nominal thickness",
                "the stack's thickness from trial to trial: closing angle, stiffness, patch",
                "procedure",
                _ALL,
                log=True,
            ),
            Estimate(
                "GRASP_RANGE_LOW_MM",
                12.0,
                8.0,
                22.0,
                "how far the hanger's adjustment moves the grasp is unmeasured: a 20-48 mm spread, ~8 mm or "
                "more from the strip's ends",
                "which stretch of cloth a trial reads, and how often trials share a spot (wear)",
                "procedure",
                _AUDIO,
                element_of="GRASP_RANGE_MM",
            ),
            Estimate(
                "GRASP_RANGE_HIGH_MM",
                52.0,
                42.0,
                56.0,
                "as the low end, within the simulated 65.5 mm strip",
                "which stretch of cloth a trial reads, and how often trials share a spot (wear)",
                "procedure",
                _AUDIO,
                element_of="GRASP_RANGE_MM",
            ),
            Estimate(
                "FOLD_LINE_NEAR_MM",
                5.0,
                2.0,
                8.0,
                "~20 mm long fingertips pinch the fold near their middle: a few mm above the fold line at least",
                "where on the strip the middle finger rubs, relative to the thumb",
                "procedure",
                _AUDIO,
                element_of="FOLD_LINE_MM",
            ),
            Estimate(
                "FOLD_LINE_FAR_MM",
                15.0,
                10.0,
                20.0,
                "at most about a fingertip's length above it",
                "where on the strip the middle finger rubs, relative to the thumb",
                "procedure",
                _AUDIO,
                element_of="FOLD_LINE_MM",
            ),
            # --- the fabric's surface and its wear ----------------------------------------------------------
            Estimate(
                "ROUGHNESS_K_MIN",
                0.5,
                0.2,
                1.0,
                "below wavelengths of 1-5 mm the draped cloth follows the fingertip rather than vibrating it",
                "the texture sound's low-frequency content",
                "fabric surface",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "WEAVE_SHARE",
                0.5,
                0.2,
                0.8,
                "the periodic weave or knit carries a fifth to most of a cloth's height variance",
                "how tonal (weave lines) against broadband each fabric's texture sound is",
                "fabric surface",
                _AUDIO,
            ),
            Estimate(
                "WEAVE_IRREGULARITY",
                0.03,
                0.01,
                0.08,
                "woven fabrics' yarn spacing varies by a few per cent (coefficient of variation)",
                "the weave lines' width",
                "fabric surface",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "WEAVE_WANDER_PERIODS",
                4.0,
                2.0,
                16.0,
                "yarn spacing drifts smoothly (yarn tension, beat-up) over a couple to a dozen and more yarns",
                "the weave lines' shape: how their irregularity is spread in frequency",
                "fabric surface",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "WEAVE_HARMONIC_SPREAD",
                0.5,
                0.2,
                0.8,
                "a yarn's cross-section sets each harmonic's weight: tens of per cent off a smooth 1/k^s "
                "trend either way",
                "the relative levels of each fabric's weave lines",
                "fabric surface",
                _AUDIO,
            ),
            Estimate(
                "LOCAL_ROUGHNESS_SPREAD",
                0.2,
                0.05,
                0.4,
                "wear, creases and pile direction change a strip's roughness by 5-40 % from place to place",
                "the texture level's change with the grasp position",
                "fabric surface",
                _AUDIO,
            ),
            Estimate(
                "LOCAL_ROUGHNESS_LENGTH_MM",
                10.0,
                3.0,
                30.0,
                "wear, creases and pile direction change over a fingertip's width to a few centimetres of cloth",
                "how far the grasp must move for the texture level to change",
                "fabric surface",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "FUZZ_FIBRES_PER_MM",
                6.0,
                2.0,
                18.0,
                "loose fibre ends on a fuzzy staple-fibre cloth: a few to tens per mm of path",
                "the loose fibres' clicks in the texture sound",
                "fabric surface",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "FUZZ_FIBRE_WIDTH_MM",
                0.008,
                0.004,
                0.02,
                "textile fibres are ~10-20 um across (wool to ~40 um); a fibre end's bump is about as wide",
                "how high in frequency the loose fibres reach",
                "fabric surface",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "FUZZ_HEIGHT",
                0.6,
                0.2,
                1.5,
                "a loose fibre end stands about as high as the cloth's RMS roughness, within a factor ~3",
                "the loose fibres' share of the texture sound",
                "fabric surface",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "SHELL_ROUGHNESS_UM",
                0.5,
                0.2,
                1.5,
                "a moulded silicone skin's micro-texture: sub-micron to ~1 um RMS",
                "class 0's texture sound and clicks (the shells rub each other)",
                "fabric surface",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "SHELL_SPECTRAL_SLOPE",
                2.0,
                1.0,
                3.0,
                "self-affine surfaces' height spectra fall as 1/k^(1 + 2H), Hurst exponent H of 0 to 1",
                "class 0's texture spectrum",
                "fabric surface",
                _AUDIO,
            ),
            Estimate(
                "CLOTH_CREEP_MM_PER_CYCLE",
                0.05,
                0.02,
                0.15,
                "about a third of the 0.1-0.3 mm stick length goes unrecovered each stroke, within a factor ~2-3",
                "how far the read stretch of cloth drifts within a trial",
                "fabric surface",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "WEAR_DOUBLING_RUBS",
                1000.0,
                250.0,
                4000.0,
                "the Martindale pilling test's stages (125-2000 rubs, ISO 12945-2) grade pills, not a fibre density",
                "how fast a cloth's loose fibres grow over its recording history",
                "fabric surface",
                _AUDIO,
                log=True,
            ),
            # --- the room and the lab's events ---------------------------------------------------------------
            Estimate(
                "ROOM_VOLUME_M3",
                144.0,
                50.0,
                400.0,
                "a university lab, unnamed by the paper: a small room (~5 x 4 x 2.7 m) to a large one (~12 x 11 x 3 m)",
                "the reverberant field against the direct: events' and the loudspeaker's level at the hand",
                "room and lab events",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "ROOM_T60_S",
                0.6,
                0.35,
                1.2,
                "ANSI S12.60's classroom target is 0.6 s, furnished offices 0.4-0.8 s, a bare lab longer",
                "the room's reverberation: its responses at the two microphones",
                "room and lab events",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "LAB_TRIAL_JITTER_DB",
                0.3,
                0.1,
                1.0,
                "the meter's 29-31 dB(A) spans the lab's days and trials; a ventilation floor moves by "
                "tenths of a dB in a day, ~1 dB with the building services",
                "the lab floor's level from trial to trial within a day",
                "room and lab events",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "LAB_VOICE_PER_MIN",
                0.2,
                0.05,
                1.0,
                "a remark every 20 minutes to one a minute on an average day; no counts in a lab were found",
                "how often a voice is heard in a trial",
                "room and lab events",
                _AUDIO,
                log=True,
                element_of="LAB_EVENTS",
            ),
            Estimate(
                "LAB_STEPS_PER_MIN",
                0.5,
                0.1,
                2.0,
                "a walk past every 10 minutes to two a minute; no counts in a lab were found",
                "how often footsteps are heard in a trial",
                "room and lab events",
                _AUDIO,
                log=True,
                element_of="LAB_EVENTS",
            ),
            Estimate(
                "LAB_DOOR_PER_MIN",
                0.05,
                0.01,
                0.25,
                "a door every 100 minutes to every 4 minutes; no counts in a lab were found",
                "how often a door is heard in a trial",
                "room and lab events",
                _AUDIO,
                log=True,
                element_of="LAB_EVENTS",
            ),
            Estimate(
                "LAB_STEPS_DB_A",
                45.0,
                38.0,
                52.0,
                "a footfall at 1 m sits some dB below conversational speech (50 dB(A)); hard heels on a hard "
                "floor reach it",
                "the footsteps' level",
                "room and lab events",
                _AUDIO,
                element_of="LAB_EVENTS",
            ),
            Estimate(
                "LAB_DOOR_DB_A",
                70.0,
                65.0,
                75.0,
                "a door closed normally: 65-75 dB(A) at 1 m",
                "the door's level",
                "room and lab events",
                _AUDIO,
                element_of="LAB_EVENTS",
            ),
            Estimate(
                "LAB_VOICE_SHORT_S",
                1.0,
                0.5,
                2.0,
                "a remark lasts from a word or two",
                "the shortest utterance",
                "room and lab events",
                _AUDIO,
                log=True,
                element_of="LAB_EVENTS",
            ),
            Estimate(
                "LAB_VOICE_LONG_S",
                4.0,
                2.0,
                8.0,
                "to a few sentences",
                "the longest utterance",
                "room and lab events",
                _AUDIO,
                log=True,
                element_of="LAB_EVENTS",
            ),
            Estimate(
                "LAB_STEPS_SHORT_S",
                3.0,
                1.5,
                5.0,
                "a walk past at ~1.4 m/s stays within a few metres for a few seconds",
                "the shortest walk past",
                "room and lab events",
                _AUDIO,
                log=True,
                element_of="LAB_EVENTS",
            ),
            Estimate(
                "LAB_STEPS_LONG_S",
                6.0,
                5.0,
                12.0,
                "or longer on a slow or longer path",
                "the longest walk past",
                "room and lab events",
                _AUDIO,
                log=True,
                element_of="LAB_EVENTS",
            ),
            Estimate(
                "LAB_DOOR_S",
                0.3,
                0.15,
                0.6,
                "a door's impact and its latch: a few tenths of a second",
                "how long a door's sound lasts",
                "room and lab events",
                _AUDIO,
                log=True,
                element_of="LAB_EVENTS",
            ),
            Estimate(
                "LAB_ACTIVITY_SIGMA",
                0.7,
                0.4,
                1.2,
                "an ICU's day-to-day level spread is 0.40 in log-activity (Naef et al. 2023), a lower bound "
                "for a lab's irregular occupancy",
                "how busy one recording day is against another",
                "room and lab events",
                _AUDIO,
            ),
            Estimate(
                "EVENT_DISTANCE_NEAR_M",
                2.0,
                1.0,
                3.0,
                "the far side of the hand's bench",
                "the nearest event",
                "room and lab events",
                _AUDIO,
                element_of="EVENT_DISTANCE_M",
            ),
            Estimate(
                "EVENT_DISTANCE_FAR_M",
                8.0,
                5.0,
                12.0,
                "the far side of the room (5-12 m for the room sizes above)",
                "the farthest event",
                "room and lab events",
                _AUDIO,
                log=True,
                element_of="EVENT_DISTANCE_M",
            ),
            Estimate(
                "STEP_DECAY_S",
                0.03,
                0.01,
                0.08,
                "a heel strike on a floor slab rings down within tens of ms",
                "each footfall's length",
                "room and lab events",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "DOOR_DECAY_SHARE",
                1 / 3,
                0.15,
                0.6,
                "the impact decays within its sound's duration: a time constant of a sixth to half of it",
                "the door's decay",
                "room and lab events",
                _AUDIO,
            ),
            # --- the joints, the force proxy and the hand's geometry -------------------------------------------
            Estimate(
                "FINGER_LEVER_MM",
                60.0,
                40.0,
                90.0,
                "joint axis to fingertip contact of a human-sized finger (the ISyHand's dimensions are unpublished)",
                "joint angle and speed per mm of fingertip travel: the joints' swing, the servos' speed and noise",
                "proprioception",
                _AUDIO_PROPRIO,
            ),
            Estimate(
                "OPEN_POSE_THUMB1_RAD",
                0.30,
                0.05,
                0.55,
                "the open hand's pose is unpublished: each joint within ~15 degrees of one that clears the gap",
                "the thumb's first joint angle (an offset)",
                "proprioception",
                _PROPRIO,
                element_of="OPEN_POSE_RAD",
            ),
            Estimate(
                "OPEN_POSE_THUMB2_RAD",
                0.20,
                -0.05,
                0.45,
                "as the first joint",
                "the thumb's second joint angle (an offset)",
                "proprioception",
                _PROPRIO,
                element_of="OPEN_POSE_RAD",
            ),
            Estimate(
                "OPEN_POSE_THUMB3_RAD",
                0.10,
                -0.15,
                0.35,
                "as the first joint",
                "the thumb's third joint angle (an offset)",
                "proprioception",
                _PROPRIO,
                element_of="OPEN_POSE_RAD",
            ),
            Estimate(
                "OPEN_POSE_MIDDLE1_RAD",
                0.00,
                -0.25,
                0.25,
                "as the first joint",
                "the middle finger's first joint angle (an offset)",
                "proprioception",
                _PROPRIO,
                element_of="OPEN_POSE_RAD",
            ),
            Estimate(
                "OPEN_POSE_MIDDLE2_RAD",
                0.20,
                -0.05,
                0.45,
                "as the first joint",
                "the middle finger's second joint angle (an offset)",
                "proprioception",
                _PROPRIO,
                element_of="OPEN_POSE_RAD",
            ),
            Estimate(
                "OPEN_POSE_PALM_RAD",
                0.50,
                0.25,
                0.75,
                "as the first joint",
                "the palm joint's angle (an offset)",
                "proprioception",
                _PROPRIO,
                element_of="OPEN_POSE_RAD",
            ),
            Estimate(
                "CLOSING_SHARE_THUMB2",
                0.6,
                0.3,
                0.8,
                "the thumb closes with its two outer joints; how it splits its travel between them is unpublished",
                "the thumb's closing angles and loads (the rest goes to its third joint)",
                "proprioception",
                _PROPRIO,
                element_of="CLOSING_SHARE",
            ),
            Estimate(
                "PALM_REACTION_SHARE",
                0.3,
                0.1,
                0.6,
                "the palm joint's axis against the rubbing direction sets how much of the strokes' reaction "
                "torque it carries; the ISyHand's kinematics are unpublished",
                "the palm joint's lag and current under the rubbing load",
                "proprioception",
                _PROPRIO,
            ),
            Estimate(
                "SERVO_STIFFNESS_NM_RAD",
                4.0,
                2.0,
                30.0,
                "a position loop's torque per rad of lag: the 1.9 N m stall torque over a proportional band "
                "of 0.06-1 rad",
                "how far loaded joints lag their command",
                "proprioception",
                _PROPRIO,
                log=True,
            ),
            Estimate(
                "VISCOUS_NM_PER_RAD_S",
                0.01,
                0.003,
                0.03,
                "a 345:1 gear train's drag at the output: of the order of a per cent of the stall torque per rad/s",
                "the moving joints' current",
                "proprioception",
                _PROPRIO,
                log=True,
            ),
            Estimate(
                "IDLE_CURRENT_A",
                0.04,
                0.015,
                0.1,
                "a holding servo draws tens of mA (the STS3215's no-load running current is 150 mA at 7.4 V)",
                "every joint's current floor",
                "proprioception",
                _PROPRIO,
                log=True,
            ),
            Estimate(
                "VELOCITY_NOISE_RAD_S",
                0.02,
                0.005,
                0.06,
                "a velocity from a 12-bit encoder's counts: a 1.5 mrad step per 25-300 ms of counting",
                "the joints' velocity noise",
                "proprioception",
                _PROPRIO,
                log=True,
            ),
            Estimate(
                "CURRENT_NOISE_A",
                0.006,
                0.002,
                0.02,
                "PWM ripple on the current reading: about one 6.5 mA register step, up to a few",
                "the joints' current noise",
                "proprioception",
                _PROPRIO,
                log=True,
            ),
            Estimate(
                "READ_LATENCY_S",
                0.002,
                0.0005,
                0.008,
                "reading six servos over a 1 Mbaud half-duplex bus takes ~1-5 ms before the frame",
                "how far the joint readings lead the frame",
                "proprioception",
                _PROPRIO,
                log=True,
            ),
            Estimate(
                "FORCE_NOISE_N",
                0.004,
                0.0015,
                0.01,
                "Insight's ~0.03 N accuracy over many contacts [insight] bounds a repeated contact's; its "
                "split into noise and day bias is unmeasured",
                "the force proxy's frame-to-frame noise",
                "proprioception",
                _PROPRIO,
                log=True,
            ),
            Estimate(
                "FORCE_BIAS_N",
                0.004,
                0.0015,
                0.01,
                "as the noise: a share of Insight's ~0.03 N accuracy, held for a day by its daily reference image",
                "the force proxy's day bias, and with it where the closing stops",
                "proprioception",
                _ALL,
                log=True,
            ),
            # --- the microphones beyond their datasheet ------------------------------------------------------
            Estimate(
                "DC_OFFSET_COUNTS",
                -3000.0,
                -8000.0,
                -1000.0,
                "the SPH0645's DC offset is large and part-specific, unspecified: ~1-6 % of the 2**17 full scale",
                "the words' DC (removed by the features' detrend)",
                "microphones",
                _AUDIO,
            ),
            Estimate(
                "DC_DRIFT_COUNTS",
                400.0,
                100.0,
                1500.0,
                "the offset follows the modulator's reference and temperature; the datasheet gives no drift: "
                "0.1-1 % of full scale",
                "the DC's day-to-day change",
                "microphones",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "DECIMATION_HZ",
                21_000.0,
                19_000.0,
                23_000.0,
                "a sigma-delta decimator's passband ends at 0.40-0.48 of the 48 kHz rate (converters: "
                "0.45-0.47); the SPH0645's is unstated",
                "where the microphones' response ends above the 15 kHz band",
                "microphones",
                _AUDIO,
            ),
            Estimate(
                "DECIMATION_ORDER",
                24.0,
                12.0,
                48.0,
                "the stopband starts near the 24 kHz Nyquist rate, ~1.15 times the edge: an order of 12-48 "
                "cuts 15-55 dB there; the SPH0645's is unstated",
                "how steeply the microphones' response ends above the decimator's edge",
                "microphones",
                _AUDIO,
                log=True,
            ),
            # --- the catalog's physical parameters, each kind scaled for every fabric alike -----------------
            Estimate(
                "CATALOG_WEAVE_PERIOD_SCALE",
                1.0,
                0.7,
                1.4,
                "weave and knit periods of the named garment kinds are known to tens of per cent (0.1-3 mm)",
                "the texture's dominant frequency at the rubbing speed",
                "fabric catalog",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "CATALOG_ROUGHNESS_SCALE",
                1.0,
                0.5,
                2.0,
                "RMS heights of textiles span 2-50 um by fabric; each of ours is a choice within a factor of 2",
                "the texture's vibration power and the stick-slip clicks' size",
                "fabric catalog",
                _AUDIO,
                log=True,
            ),
            Estimate(
                "CATALOG_FRICTION_SCALE",
                1.0,
                0.8,
                1.25,
                "silicone-on-textile friction of 0.2-0.9 is known per fabric kind to about a fifth",
                "stick length, trial length, stick-slip and the joints' load",
                "fabric catalog",
                _ALL,
                log=True,
            ),
            Estimate(
                "CATALOG_THICKNESS_SCALE",
                1.0,
                0.7,
                1.4,
                "one layer's thickness of a garment kind varies by tens of per cent between weights",
                "the stack the fingers pinch: the closing, the patch's size and the fold ridge",
                "fabric catalog",
                _ALL,
                log=True,
            ),
            Estimate(
                "CATALOG_COMPRESSIBILITY_SCALE",
                1.0,
                0.7,
                1.3,
                "how much a stack gives at 0.1 N: a choice per fabric kind, tens of per cent either way",
                "the stack's give under the grasp, and the patch's conformity",
                "fabric catalog",
                _ALL,
            ),
            Estimate(
                "CATALOG_STRETCH_STIFFNESS_SCALE",
                1.0,
                0.5,
                2.0,
                "in-plane stiffness of a gripped strip: N/mm of order one to ten by weave and weight, a factor of 2",
                "the cloth's give under the friction load and its bending stiffness",
                "fabric catalog",
                _ALL,
                log=True,
            ),
            Estimate(
                "CATALOG_FUZZ_SCALE",
                1.0,
                0.5,
                1.5,
                "loose-fibre density of staple fabrics: a choice per fabric from none to pile, half to one and a half",
                "the scratching of loose fibres in the texture",
                "fabric catalog",
                _AUDIO,
            ),
            # --- effects the published simulator leaves out (value 0), bounded by physics ------------------
            Estimate(
                "CONTACT_SHIFT_PER_STACK_MM",
                0.0,
                0.0,
                0.2,
                "closing on arcs, a stack thicker by t turns the contact along the shell by R t / 2L: "
                "0.1-0.2 mm per mm for L 60-30 mm; 0 leaves it out",
                "where the contact lands in the frame with the fabric's thickness (up to ~1 mm, a few pixels at 60x80)",
                "camera effects left out",
                _IMAGES,
            ),
        )
    }
)

GROUPS: tuple[str, ...] = tuple(dict.fromkeys(e.group for e in ESTIMATES.values()))


_overrides: dict[str, float] = {}  # set by `override`: the values in force instead of the registry's


def value(name: str) -> float:
    """The value of estimate `name` in force: the registry's, unless `override` set another."""
    return _overrides.get(name, ESTIMATES[name].value)


def constants() -> dict[str, float]:
    """Every estimate that is a `calibration` constant of its own name (no `element_of`), at the
    value in force (`value`): `calibration` binds them when it is executed."""
    return {e.name: value(e.name) for e in ESTIMATES.values() if e.element_of is None}


def in_force() -> tuple[tuple[str, float], ...]:
    """The overrides in force (`override`), as `Scene.estimates` carries them: sorted pairs."""
    return tuple(sorted(_overrides.items()))


def fingerprint() -> str:
    """The simulator's magnitudes as results record them (`reporting.results_files.fingerprints`):
    sha256 over every estimate's name and the value in force (`value`)."""
    text = "\n".join(f"{name}={value(name)!r}" for name in sorted(ESTIMATES))
    return hashlib.sha256(text.encode()).hexdigest()


def override(values: Mapping[str, float]) -> None:
    """Put `values` (estimate name -> value, each within its range) in force instead of the
    registry's, and every other estimate back to the registry's value. Modules read estimates
    when they are executed: `trial.use_estimates` executes `calibration` again after this."""
    checked = check(values)
    _overrides.clear()
    _overrides.update(checked)


def calibrated_in(study: str) -> list[dict]:
    """The calibrations matched to a number of `study`'s table, as its results record them."""
    return [
        {
            "estimate": e.name,
            "value": e.value,
            "measurement": e.calibrated.measurement,
            "fitted_on": e.calibrated.fitted_on,
        }
        for e in ESTIMATES.values()
        if e.calibrated is not None and e.calibrated.study == study
    ]


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


TABLE_BEGIN = "<!-- ESTIMATES_BEGIN -->"
TABLE_END = "<!-- ESTIMATES_END -->"


def _number(v: float) -> str:
    return f"{v:g}"


def markdown_table() -> str:
    """The registry as Markdown: per group, one row per estimate (value, range, scale, streams, why
    this range, what it drives, and the measurement it is calibrated to, where it is)."""
    lines = [f"{len(ESTIMATES)} estimates in {len(GROUPS)} groups (the sensitivity study's factors).", ""]
    for group in GROUPS:
        lines += [
            f"**{group}**",
            "",
            "| estimate | value | range | scale | streams | why this range | drives |",
            "|---|---|---|---|---|---|---|",
        ]
        for e in ESTIMATES.values():
            if e.group != group:
                continue
            drives = e.drives
            if e.calibrated is not None:
                c = e.calibrated
                drives += (
                    f"; calibrated to {c.measurement} ({_number(c.paper_value)}, {c.where}), fitted on {c.fitted_on}"
                )
            cells = [
                f"`{e.name}`",
                _number(e.value),
                f"{_number(e.low)} to {_number(e.high)}",
                "log" if e.log else "lin",
                ", ".join(e.streams),
                e.reason,
                drives,
            ]
            lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
        lines.append("")
    return "\n".join(lines)


def with_table(text: str) -> str:
    """`text` (a document holding `TABLE_BEGIN` and `TABLE_END` once each) with the block between
    them rewritten to `markdown_table()`."""
    if text.count(TABLE_BEGIN) != 1 or text.count(TABLE_END) != 1:
        raise ValueError(f"the document must hold {TABLE_BEGIN} and {TABLE_END} once each")
    before, rest = text.split(TABLE_BEGIN)
    _, after = rest.split(TABLE_END)
    return f"{before}{TABLE_BEGIN}\n{markdown_table()}{TABLE_END}{after}"
