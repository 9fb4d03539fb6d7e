"""Every physical constant of the scene simulator, in one place, with where it comes from.

Calibration is by physical parameters only: levels, SNRs and bands from the paper and the
SPH0645 datasheet, physical laws, cited material and geometry constants, and declared estimates.
Nothing here was tuned to a classification accuracy. Every number has one of three origins:

* a published source, tagged in the comment on its line or in the comment block directly above
  it ("[paper, Section]" names where, "[paper: ...]" what it says):

    [paper]     stated in the paper (arxiv_main.tex, Method / Experiments)
    [ds]        SPH0645LM4H datasheet (Knowles): -26 dBFS at 94 dB SPL, 65 dB(A) SNR, AOP 120 dB
                SPL, 18 valid bits of a 24-bit word in a 32-bit I2S slot, usable band 50 Hz-15 kHz
    [minsight]  Minsight's publication and open design files (see "Minsight images")
    [insight]   Insight's publication, Minsight's parent design (see "Minsight images")
    [FACTS]     an established property of the phenomenon from outside the paper and the
                datasheet (texture vibration f = v / lambda, babble spectra, magnetic encoders),
                stated where it is used
    [cited]     a named publication, standard or datasheet, given in that comment
    [law]       a physical constant or law (sound speed in air, gamma P0, 0 C in kelvin)

* an estimate, declared in `fabricjax.sim.estimates` with its range, a physical reason for that
  range and what it drives (`[estimate]` in the comments here, which give the longer reasons and
  name it in backquotes where it enters). It is a constant of this module under its own name, bound
  from the registry below; an element of a range, a position or a unit conversion is read with
  `estimates.value("NAME")` where that constant is built. A calibration to one measurement of the
  paper is an estimate whose registry entry says so (`calibrated`).
* `[numerics]`: a numerical or implementation setting (grid, supersampling, lead-in, a reference
  point that only states where an estimate is given), not a physical magnitude.

An expression of other constants (a unit conversion, a derived geometry) needs no tag of its own.
`tests/test_estimates.py` reads this file and every module of `fabricjax.sim` and fails on a
number with none of these.
"""

from __future__ import annotations

import math

from fabricjax.sim import estimates
from fabricjax.store import archive

# Every estimate of the registry, at the value in force when this module is executed: the
# registry's, or an override's (`trial.use_estimates` executes the module again after one).
globals().update(estimates.constants())

# --- time base --------------------------------------------------------------------------------
# [paper] The audio sample rate (48 kHz), the step rate (50 Hz, one step per Minsight frame) and the
# audio samples per step (2048) are the archive format's: `archive.AUDIO_RATE`, `STEP_RATE`, `WINDOW`.
LEAD_IN = 4096  # [numerics] samples recorded before the procedure starts (>= archive.WINDOW so every window is full)
# [estimate] `FRAME_JITTER_S`, USB camera frame-time jitter: a UVC camera delivers frames on its own
# clock; the host timestamps them at USB transfer with ~1 ms scheduling jitter (a USB 2.0 microframe
# is 125 us; Linux user-space wake-up latency is ~0.1-1 ms), hence +-0.8 ms
CONTROL_HZ = 2000  # [numerics] grid on which the finger motion is integrated (then interpolated to 48 kHz)

# --- finger motion [paper: force-controlled closing until 0.1 N, then rubbing cycles] ---------
GRASP_FORCE_N = 0.1  # [paper] closing stops when Minsight's force estimate reaches this
CYCLES_PER_TRIAL = 50  # [paper, Experiments] rubbing cycles per trial (`Scene.cycles`' default)
# [estimate] `OPEN_GAP_MM`: fingertip gap of the open pose
# [estimate] `CLOSING_SPEED_MM_S`: relative fingertip closing speed (same for every fabric [paper])
# [estimate] `SHELL_NORMAL_STIFFNESS_N_MM`: two soft silicone shells in series, normal direction (Hertz
# with the Ecoflex datasheet's modulus, below in "Minsight images", gives 0.27 mm per shell at 0.1 N:
# consistent)
# [estimate] `SHELL_SHEAR_STIFFNESS_N_MM`: shear stiffness of one shell at the contact
# [estimate] `SETTLE_S`: pause between the grasp and the first rubbing stroke
# [estimate] `STOP_S`: recording continues briefly after the last stroke
# [estimate] `RUB_AMPLITUDE_MM`: each fingertip moves +-3 mm laterally, the two in opposite phase
# [estimate] `RUB_RAMP_CYCLES`: the preprogrammed strokes start from rest: the stroke's amplitude ramps
# up linearly over this part of the first cycle (a servo's acceleration limit; the first quarter stroke)
# [estimate] `CYCLE_HZ`, the commanded rubbing frequency: 50 cycles ~ 25 s before the load droop; with
# the closing and the droop, the paper's ~1500 steps per 50-cycle trial [paper, Experiments]
# [estimate] `ARC_MM`: extra indentation at the stroke ends (the fingertips move on arcs)
# [estimate] `FINGER_LEVER_MM`: joint axis to fingertip contact
# [paper: "the fingers move more slowly when finger-fabric friction is high"] Position-controlled
# hobby servos lose speed under load: speed = commanded / (1 + SPEED_DROOP_PER_N * mu * F_n).
# [estimate] `SPEED_DROOP_PER_N`: 2 / N gives ~6 % (mu = 0.25) to ~22 % (mu = 0.95) slower cycles at
# 0.1-0.15 N: trials of ~1300-1550 steps.
# [estimate] `SPEED_JITTER`: an STS3215's no-load speed is proportional to its supply voltage
# (datasheet: 0.222 s/60 deg at 7.4 V, 0.16 s/60 deg at 12 V, i.e. ~6 %/V); a bench supply under a
# varying load sags by ~0.1-0.2 V: a per-trial spread of ~2 % of the rubbing rate.
# [estimate] `CYCLE_PHASE_JITTER`: slow wander of the stroke rate within a trial: half the per-trial spread
# [estimate] `CYCLE_WANDER_S`: the wander is a random walk with one step per this time (linearly
# interpolated between them): the supply's and the load's fluctuations change over tens of ms to a stroke
# [estimate] `CLOTH_CREEP_MM_PER_CYCLE`: the hanging cloth creeps between strokes (random walk): a
# stroke's net slip is the stick length mu F_n / k_t ~ 0.1-0.3 mm; about a third of it is not
# recovered on the way back.

# --- the catalog's physical parameters (`catalog.py`: our textbook-order choices, not measurements) ---
# [estimate] Each kind of parameter is scaled by one factor for every fabric alike (`scene.simulated_fabric`):
# 1, the catalog as it is, in the published data; the registry declares how far each could be off
# (`CATALOG_WEAVE_PERIOD_SCALE`, `CATALOG_ROUGHNESS_SCALE`, `CATALOG_FRICTION_SCALE`,
# `CATALOG_THICKNESS_SCALE`, `CATALOG_COMPRESSIBILITY_SCALE`, `CATALOG_STRETCH_STIFFNESS_SCALE`,
# `CATALOG_FUZZ_SCALE`).

# --- fabric surface [FACTS: f = v / lambda; roughness spectrum 1/f^s; fuzz] -----------------------
PROFILE_DX_MM = 0.001  # [numerics] 1 um grid: resolves content to > 20 kHz at the fastest slide speed
PROFILE_LEN_MM = 65.536  # [numerics] one simulated cloth strip per fabric (2**16 samples); grasps land anywhere on it
# [paper: "after each trial, the position of the clothes hanger was adjusted to create variation
# in the grasping location"] [estimate] The grasp lands anywhere in this range of the strip, at
# least one contact length (~10 mm) from its ends: a different stretch of cloth for every trial.
GRASP_RANGE_MM = (estimates.value("GRASP_RANGE_LOW_MM"), estimates.value("GRASP_RANGE_HIGH_MM"))
# [estimate] `ROUGHNESS_K_MIN`: cycles/mm: below (2 mm wavelengths) the fabric drapes rather than vibrates
# [estimate] `WEAVE_SHARE`: fraction of the RMS height in the periodic weave (the rest: random roughness)
WEAVE_HARMONICS = 8  # [numerics] the weave's Fourier series, cut where its harmonics' weights m^(-s/2) have faded
# [estimate] `WEAVE_HARMONIC_SPREAD`: each harmonic's weight departs from the m^(-s/2) trend by a factor
# U(1 - x, 1 + x), per fabric (yarn shape)
# [estimate] `WEAVE_IRREGULARITY`: yarn spacing varies by ~3 % of the period
# [estimate] `WEAVE_WANDER_PERIODS`: the spacing's irregularity is smooth over this many weave periods
# (its spectrum ends at 1 / (this x period))
# [estimate] `LOCAL_ROUGHNESS_SPREAD`: local roughness varies +-20 % along the strip (10 mm correlation):
# wear, creases, pile direction
# [estimate] `LOCAL_ROUGHNESS_LENGTH_MM`: that variation's correlation length: its spectrum ends at 1 / this
# [estimate] `FUZZ_FIBRES_PER_MM`: loose fibre ends per mm of path at fuzz = 1
# [estimate] `FUZZ_FIBRE_WIDTH_MM`: a fibre end's bump: fibre diameters are ~10-20 um
# [estimate] `FUZZ_HEIGHT`: fibre bump height relative to the fabric's RMS roughness
# [estimate] `SHELL_ROUGHNESS_UM`: the silicone skin's own micro-texture: all class 0 rubs against
# [estimate] `SHELL_SPECTRAL_SLOPE`: its height spectrum's slope

# --- contact sound in the Minsound cavity ---------------------------------------------------------
# [law] Adiabatic cavity: p = gamma * P0 * dV / V (air: gamma = 1.4, P0 = 101 325 Pa). The fabric
# profile displaces the outer skin; a fraction of that reaches the inner wall through ~3 mm of
# silicone over the contact patch.
GAMMA_P0_PA = 1.4 * 101_325.0
# [estimate] `CONTACT_AREA_M2`: ~5 mm x 4 mm contact patch at 0.1 N
# [estimate] `WALL_COUPLING`: inner-wall displacement per outer-surface displacement
# [estimate] `CAVITY_VOLUME_M3`: ~8 cm^3 of air inside the shell
TEXTURE_PA_PER_UM = (  # ~3.5e-3
    GAMMA_P0_PA
    * estimates.value("CONTACT_AREA_M2")
    * estimates.value("WALL_COUPLING")
    * 1e-6
    / estimates.value("CAVITY_VOLUME_M3")
)
# [estimates] Shell wall: mass-spring wall mode (`SHELL_MODE_HZ`, `SHELL_MODE_Q`) with viscoelastic
# losses (silicone damping rises with f: exp(-f / `SHELL_LOSS_HZ`) extra).
# Stick-slip: micro-slips per mm slid grow with friction; each releases energy at asperity scale
# (amplitude ~ mu * F_n * asperity height), plus one larger release at every stroke reversal
# (elastic energy 1/2 k delta^2 stored in the stuck shell and stretched cloth).
# [estimates] all but the reference point (SLIP_PA and RELEASE_PA are given at it).
# `SLIPS_PER_MM`: at mu = 1
# `SLIP_PA`: click peak pressure at mu * F_n = 0.05 N and 20 um asperities
SLIP_REF_FORCE_N = 0.05  # [numerics] the reference point SLIP_PA and RELEASE_PA are given at: mu * F_n
SLIP_REF_ROUGHNESS_UM = 20.0  # [numerics] and asperity height (releases grow no further above it)
# `RELEASE_PA`: reversal release at delta = 0.1 mm, mu * F_n = 0.05 N, 20 um asperities
RELEASE_REF_SLIP_MM = (
    0.1  # [numerics] the stick length delta RELEASE_PA is given at (releases grow as sqrt(delta / this))
)
SLIP_RING_HZ = (
    estimates.value("SLIP_RING_LOW_HZ"),
    estimates.value("SLIP_RING_HIGH_HZ"),
)  # contact/skin ring of a slip click
# `SLIP_RING_SPREAD`: the trial's ring is off the stiffness's by a factor U(1 - x, 1 + x)
# `SLIP_DECAY_S`: how long each click rings
# `SLIP_SPREAD`: log-normal sigma of click amplitudes

# --- air paths: what each microphone hears of the contacts -------------------------------------
# Geometry [estimates for the ISyHand: the paper gives no drawing with dimensions]: the pinch
# point on the fold is the origin, the pinch axis (thumb to middle finger, normal to the cloth) is x.
# Each fingertip's centre lies half a shell width plus half the folded stack from the cloth: the
# 15 mm below is half the 30 mm width estimated before the shell's published radius (11.8 mm,
# `SHELL_OUTER_RADIUS_MM`) was known; with it the centres sit ~12.3 mm from the pinch, which moves
# the palm's distances to the fingertips by < 2 mm (< 0.2 dB at 7-9 cm), not yet simulated. The
# palm microphone sits "on the side of the palm" [paper] ~8 cm from the pinch, below and behind it.
# The zeros place the fingertips on the pinch axis [numerics: the frame's choice].
THUMB_TIP_M = (-estimates.value("FINGERTIP_OFFSET_M"), 0.0, 0.0)  # Minsound's shell (and its microphone) on the thumb
MIDDLE_TIP_M = (-THUMB_TIP_M[0], 0.0, 0.0)  # Minsight's shell on the middle finger, opposite [numerics: on the axis]
# 7.9 cm from the pinch, 7.4 cm from the thumb, 8.6 cm from the middle finger
PALM_MIC_M = (estimates.value("PALM_MIC_X_M"), estimates.value("PALM_MIC_Y_M"), estimates.value("PALM_MIC_Z_M"))
SOUND_SPEED_M_S = 343.0  # [law] air at 20 C
AIR_DENSITY_KG_M3 = 1.2  # [law] air at 20 C; rho c^2 = gamma P0 for an ideal gas
# [cited] Each fingertip radiates as a pulsating sphere (Kinsler, Frey, Coppens & Sanders,
# Fundamentals of Acoustics, 4th ed., Wiley 2000, Sec. 7.3): silicone is incompressible, so the
# shell's outer surface changes volume by exactly its cavity's dV, and p(r) = rho w^2 dV / (4 pi r
# (1 + j k a)) with a half the shell's width (`air_path.fingertip_radiation`): -52 dB re the cavity
# pressure at 1 kHz and 8 cm, +12 dB per octave up to k a = 1 (3.6 kHz). Minsight's shell is built as
# Minsound's (silicone on a rigid skeleton, the same contact patch) [paper, Hardware], so its
# contact radiates by the same law from its own centre.
# [cited] The cloth between the fingertips is a limp sheet (membrane waves in hanging cloth travel
# at ~1 m/s and die within a millimetre at audio frequencies), so it radiates from the contact patch
# only: an unbaffled rigid disc of the patch's radius oscillating normal to itself, a dipole whose
# far field is p = rho c^2 k^3 (2 a^3 / (3 pi)) xi cos(theta) / r (Lamb, Hydrodynamics, 6th ed.
# 1932, Sec. 102: added mass 8 rho a^3 / 3 of a disc; Pierce, Acoustics, ASA 1989, Sec. 4.4: far
# field of a dipole of that strength): +18 dB per octave for a given displacement.
CLOTH_RADIATOR_RADIUS_M = math.sqrt(estimates.value("CONTACT_AREA_M2") / math.pi)  # 2.5 mm: the contact patch
# [estimate] Only the patch's area-mean motion radiates (relief of microns to a millimetre, far shorter
# than the 5 mm patch, averages out; its mean is what changes the cavity volume, `WALL_COUPLING`),
# and the sheet between two equal soft shells in series moves by half the difference of the two
# skins' mean displacements (the stack is far stiffer than the shells at 0.1 N). So the cloth's
# dipole is ~0.16 k a below a fingertip's monopole: -30 dB at 4 kHz; it matters only above ~8 kHz,
# where the shell's wall mode has cut the fingertips' own radiation: `CLOTH_DISPLACEMENT_SHARE`.
# [paper: the fingers rub a fold of the hanging cloth] [estimate] The middle finger's Minsight shell rubs
# the other face of the fold: an independent patch of the same cloth strip, as far along the strip
# as twice the pinch's distance from the fold line (the grasp lands 5-15 mm above the fold: the
# fingertips are ~20 mm long and pinch the fold near its middle), moving opposite to the thumb.
FOLD_LINE_MM = (estimates.value("FOLD_LINE_NEAR_MM"), estimates.value("FOLD_LINE_FAR_MM"))
# Paths judged and left out, each bounded by the magnitudes above:
# * Relief of one face reaching the other fingertip through the stack: through an elastic layer of
#   thickness d, relief of wavenumber k = 2 pi / lambda passes as (1 + kd) e^(-kd) (incompressible,
#   see the Minsight section; a compressible stack passes less); at the rubbing speed (<= 40 mm/s)
#   audio frequencies have lambda <= 0.8 mm and the folded stack is >= 0.16 mm thick (two layers of
#   the thinnest cloth): >= 3.8 dB down at 50 Hz, > 85 dB down from 500 Hz.
# * Cloth-on-cloth rubbing inside the fold: the motion keeps the cloth in place and the fingertips
#   slide on it [paper: the hanger holds the cloth], so the two layers move against each other only
#   by the cloth's stretch under the friction load, mu F_n / stretch_stiffness <= 0.13 N / 0.5 N/mm
#   = 0.26 mm per stroke at <= 2 mm/s: relief of >= 10 um (a fibre) passes at <= 200 Hz, where the
#   dipole above radiates > 100 dB below the cavity pressure (`palm_physics`, "The paths").
# * Structure-borne sound through the hand to the palm microphone: a MEMS diaphragm (~1 um of
#   polysilicon, 2.3e-3 kg/m^2; Scheeper, van der Donk, Olthuis & Bergveld, A review of silicon
#   microphones, Sensors and Actuators A 44, 1994) reads an acceleration a as a pressure m'' a. The
#   contact's audio-band force (shell stiffness x skin displacement, 0.25 N/mm x ~5 um ~ 1 mN)
#   shakes at least a finger link and its servo (~0.1 kg): ~0.01 m/s^2, i.e. ~2e-5 Pa (~1 dB SPL),
#   below the microphone's own noise in every octave band. Into Minsound the contact's force acts
#   directly (the shell transfer below), which dwarfs any share that returns through the skeleton.
# [cited] Mass law for the shell wall (Beranek & Ver, Noise and Vibration Control Engineering, Wiley
# 1992, Ch. 9: field-incidence TL = 20 log10(f m'') - 47 dB), with m'' the shell's construction:
# silicone of 1.07-1.1 g/cm^3 (Smooth-On Ecoflex / Dragon Skin technical bulletins) times the
# Minsight-section shell thickness (`shell.transmission_loss_db`).
SILICONE_DENSITY_KG_M3 = 1100.0
MASS_LAW_DB = (
    47.0  # [cited] Beranek & Ver 1992, Ch. 9: the field-incidence mass law's constant (f in Hz, m'' in kg/m^2)
)
# [estimate] `SHELL_TL_MIN_DB`: leaks around the base and the stiffness-controlled region at low frequency
# [estimate] `SHELL_TL_MAX_DB`: flanking through the aluminium skeleton

# --- servo noise (heard by both microphones, also in class 0) ---------------------------------------
# [estimates] No published acoustic measurement of the STS3215 or of a comparable serial-bus or
# micro servo was found: the STS3215's datasheet gives speed, torque and current, no noise, and the
# published robot-noise figures are whole-robot airborne levels at an unstated distance, not what
# reaches a sealed fingertip cavity through the skeleton. Only the gear ratio is the datasheet's; the
# levels (dB SPL inside the shell), the pinion, the load reference, the band and the palm's share are
# order-of-magnitude estimates.
GEAR_RATIO = 345.0  # [cited] STS3215 datasheet: 1:345 gear train
# [estimate] `GEAR_TEETH`: first-stage pinion: mesh frequency = motor rev/s * teeth
# [estimate] `SERVO_TONE_PA`: gear-mesh tone at 1 rad/s joint speed, as heard inside the shell (~50 dB)
# [estimate] the tone's 2nd and 3rd harmonics, in amplitude relative to the mesh frequency's (-6 and -12 dB)
SERVO_HARMONICS = (estimates.value("SERVO_HARMONIC_2"), estimates.value("SERVO_HARMONIC_3"))
# [estimate] `SERVO_BROADBAND_PA`: motor/gear broadband noise at 1 rad/s
# [estimate] `SERVO_HOLD_PA`: holding servos' PWM hum (always present, ~34 dB)
# [estimate] `SERVO_LOAD_REF_NM`: torque at which the gear noise doubles
# [estimate] structure-borne band into the Minsound cavity
SERVO_STRUCTURE_BAND_HZ = (estimates.value("SERVO_BAND_LOW_HZ"), estimates.value("SERVO_BAND_HIGH_HZ"))
# [estimate] `SERVO_PALM_GAIN_DB`: airborne at the palm (the servos sit in the palm) vs structure-borne

# --- ambient sound: the room, its events and the cafe loudspeaker -----------------------------
# [paper, Robustness] Sound meter (Sauter SU 130, A-weighted) near the palm microphone: lab 29-31 dB,
# cafe noise 47-55 dB. `scene.nuisance` draws the level per day and trial within these ranges: the
# lab's steady floor, and the loudspeaker's sound at the palm in the cafe condition.
LAB_DB_A = (29.0, 31.0)
# [estimate] `LAB_TRIAL_JITTER_DB`: within a day, each lab trial's floor is the day's +-this (uniform),
# kept within LAB_DB_A
CAFE_DB_A = (47.0, 55.0)  # [paper]
# [estimate] `CAFE_DAY_SPREAD_DB`: a cafe day sits at U(48, 54), each trial +-1 dB, all within 47-55
# [estimate] `CAFE_TRIAL_JITTER_DB`: each cafe trial is the day's level +-this (uniform), kept within CAFE_DB_A
# [cited] The lab floor (ventilation, building services): the shape of Beranek's noise-criterion curve NC-25
# (Beranek, Revised criteria for noise in buildings, Noise Control 3(1), 1957; ANSI S12.2), octave
# band levels in dB at 63 Hz-8 kHz; only its shape is used, scaled to the drawn dB(A) level.
LAB_FLOOR_OCTAVE_DB = {63: 54.0, 125: 44.0, 250: 37.0, 500: 31.0, 1000: 27.0, 2000: 24.0, 4000: 22.0, 8000: 21.0}
# The room [estimates for a university lab; the paper names none]: 8 x 6 x 3 m (`ROOM_VOLUME_M3`) with a
# mid-frequency reverberation time (`ROOM_T60_S`) of 0.6 s (the classroom target of ANSI S12.60-2002;
# offices 0.4-0.8 s). Sabine absorption A = 0.161 V / T60 = 39 m^2, room constant R ~ A: the reverberant
# field (4 / R) equals the direct field of a Q = 1 source (Q / 4 pi r^2) at 0.9 m (Hopkins & Stryker
# 1948, in Beranek, Acoustics, 1954, Ch. 10).
SABINE_S_PER_M = 0.161  # [law] Sabine's equation T60 = 0.161 V / A: 24 ln 10 / c, in s/m
# Between the palm microphone and Minsound (7.4 cm apart) a diffuse field has the coherence
# sin(k d) / (k d) (Cook, Waterhouse, Berendt, Edelman & Thompson, Measurement of correlation
# coefficients in reverberant sound fields, JASA 27, 1955): near 1 below ~1 kHz, small above 2.3 kHz.
# Lab events [day-to-day: how busy the lab is]: talk, footsteps, doors. Each kind: mean rate per
# minute on an average day, A-weighted level at 1 m in free field, duration (s).
# * voice: conversational speech in quiet, 50 dB(A) at 1 m (van Heusden, Plomp & Pols, Effect of
#   ambient noise on the vocal output ..., Applied Acoustics 12, 1979; Pearsons, Bennett & Fidell,
#   Speech levels in various noise environments, EPA-600/1-77-025, 1977: 50-55 dB(A) casual-normal),
#   long-term speech spectrum (`SPEECH_OCTAVE_DB`), 1-4 s utterances, syllabic envelope at 4 Hz
#   (Houtgast & Steeneken, A review of the MTF concept in room acoustics, JASA 77, 1985: the speech
#   envelope spectrum peaks at 3-4 Hz); rate an estimate (a remark every five minutes);
# * steps: a walk past, footfalls at the walking cadence 1.9 Hz (Pachi & Ji, Frequency and velocity
#   of people walking, The Structural Engineer 83, 2005), each a floor impact of a few dB(A) below
#   speech at 1 m, low-passed at 500 Hz (impact sound of a shod heel on a concrete floor is strongest
#   below 500 Hz; ISO 717-2 reference spectra); rate an estimate;
# * door: a door closing, an impact of ~70 dB(A) at 1 m (an estimate: a door closed normally,
#   65-75 dB(A)), broadband, 0.3 s long; rate an estimate.
# No published counts of voices, footsteps or door closings per hour in a laboratory or office were
# found (surveys of occupied offices, e.g. "Sound in occupied open-plan offices: objective metrics with
# a review of historical perspectives", arXiv:2305.01762, 2023, report levels and their LA10 - LA90
# spread, not events), nor a footstep or door level at 1 m in the same room (ISO 717-2 and EN 16205,
# Laboratory measurement of walking noise on floors, rate floors and coverings under a standard
# tapping machine, not a person's step): rates, the step and door levels, the day's activity spread
# and the distances stay estimates.
# With these rates a trial of ~30 s holds an event about one time in three, and the events' long-term
# level (~34 dB(A)) stays a few dB above the meter's 29-31 dB: the paper's reading is the floor between
# events. Each day draws its activity (a log-normal factor on every rate, sigma 0.7 [an estimate,
# `LAB_ACTIVITY_SIGMA`]: a quiet day has a quarter, a busy one four times the mean rate). The nearest
# published day-to-day spread, an intensive care unit's 8-h day-shift level over one week, 52.0 +- 1.75
# dB(A) (Naef et al., Characterization of sound pressure levels and sound sources in the intensive care
# unit: a 1 week observational study, Frontiers in Medicine 10, 2023), is 1.75 / (10 log10 e) = 0.40 in
# log-activity if occupancy sets the level: a lower bound for a university lab, whose occupancy is far
# less regular than a ward's round-the-clock staffing. Each event's distance is uniform in 2-8 m (the
# far side of the hand's bench to the far side of the room); its level at the hand is the direct plus
# the reverberant field (Hopkins-Stryker), its sound reaches the two microphones through the room's
# responses (beyond the 0.9 m critical distance the reverberant field dominates).
# [cited] The voice's 50 dB(A) at 1 m (van Heusden et al.; Pearsons et al., above); every other number an estimate.
LAB_EVENTS = {  # kind: (per minute, dB(A) at 1 m, (shortest, longest) seconds)
    "voice": (
        estimates.value("LAB_VOICE_PER_MIN"),
        50.0,
        (estimates.value("LAB_VOICE_SHORT_S"), estimates.value("LAB_VOICE_LONG_S")),
    ),
    "steps": (
        estimates.value("LAB_STEPS_PER_MIN"),
        estimates.value("LAB_STEPS_DB_A"),
        (estimates.value("LAB_STEPS_SHORT_S"), estimates.value("LAB_STEPS_LONG_S")),
    ),
    "door": (
        estimates.value("LAB_DOOR_PER_MIN"),
        estimates.value("LAB_DOOR_DB_A"),
        (estimates.value("LAB_DOOR_S"), estimates.value("LAB_DOOR_S")),
    ),
}
EVENT_DISTANCE_M = (estimates.value("EVENT_DISTANCE_NEAR_M"), estimates.value("EVENT_DISTANCE_FAR_M"))
SYLLABLE_HZ = 4.0  # [cited] Houtgast & Steeneken 1985: the speech envelope peaks at 3-4 Hz
STEP_HZ = 1.9  # [cited] Pachi & Ji 2005: the walking cadence
STEP_LOWPASS_HZ = 500.0  # [cited] a shod heel on a concrete floor: strongest below 500 Hz (ISO 717-2 reference spectra)
# [estimate] `STEP_DECAY_S`: a heel strike on a floor slab rings down within tens of ms
# [estimate] `DOOR_DECAY_SHARE`: the door's impact decays with a time constant of a third of its 0.3 s
# [cited] The cafe [paper: "loud background noise resembling ambient sound in a coffee shop", "while playing
# audible noise"]: a recording played from a loudspeaker. Its long-term spectrum is that of babble,
# i.e. of speech (many talkers sum to the long-term average speech spectrum, which is the same across
# languages within a few dB: Byrne et al., An international comparison of long-term average speech
# spectra, JASA 96(4), 1994): octave levels of normal-effort speech, ANSI S3.5-1969 (250-4000 Hz, as
# tabulated in Crocker, Handbook of Noise and Vibration Control, Wiley 2007, Table 4.3, peaks - 12 dB)
# and the 125 Hz and 8 kHz octaves from Byrne et al. 1994's universal LTASS (125 Hz ~3 dB below the
# 250 Hz octave; flat from 4 to 8 kHz). Only the shape is used; the level is the paper's.
SPEECH_OCTAVE_DB = {125: 57.5, 250: 60.5, 500: 62.0, 1000: 56.0, 2000: 50.0, 4000: 45.0, 8000: 45.0}
# [estimate] `BABBLE_MODULATION`, the babble's residual syllabic modulation: the summed envelope of N
# independent talkers fluctuates about 1 / sqrt(N) as much as one talker's, so it shrinks as the room
# fills; 0.25 is many talkers (~16 at a single talker's full modulation). Neither the paper's
# recording's talker count nor a published modulation depth of coffee-shop noise was found.
# [estimates] Clatter of cups, plates and cutlery: rate (`CLATTER_PER_S`), ring band, decay
# (`CLATTER_DECAY_S`) and peak level. The one published figure found, dish handling in a home kitchen
# ("Common Transient Sounds: The Kitchen is a Very Noisy Place", The Hearing Review, January 1995), has
# instantaneous peaks usually above 80 dB against a sound-meter reading of 70-75 dB(A): peaks at least
# 5-10 dB above the meter's average, a bound the 12 dB below is consistent with, not a value for a cafe;
# restaurant surveys report equivalent levels, not clatter events.
CLATTER_RING_HZ = (estimates.value("CLATTER_RING_LOW_HZ"), estimates.value("CLATTER_RING_HIGH_HZ"))
# `CLATTER_PEAK_DB`: clatter peaks above the babble RMS
CLATTER_PARTIALS = (
    3  # [numerics] each clink is drawn as this many inharmonic partials in CLATTER_RING_HZ (the model's structure)
)
# `CLATTER_DECAY_SPREAD`: each clink's decay is CLATTER_DECAY_S x U(1 - x, 1 + x)
# `CLATTER_LEVEL_SPREAD`: log-normal sigma of the clinks' amplitudes
# [estimate; the paper does not place the loudspeaker, and no description of its noise playback beyond
# "while playing audible noise" was found] A loudspeaker on a table 0.5-2 m from the hand, in a
# direction drawn per cafe day; a small box radiates with directivity Q ~ 2 (`SPEAKER_Q`) towards the
# hand (Beranek, Acoustics, 1954, Ch. 4: a closed box is omnidirectional at low and beamed at high
# frequencies). Its direct sound reaches each microphone along its own path and delay; the reverberant
# sound through the room's response at each microphone.
SPEAKER_DISTANCE_M = (estimates.value("SPEAKER_DISTANCE_NEAR_M"), estimates.value("SPEAKER_DISTANCE_FAR_M"))

# --- SPH0645 [ds] -------------------------------------------------------------------------------
SENSITIVITY_DBFS = -26.0  # at 94 dB SPL (1 Pa)
# 18 valid bits, full scale 2**17: `archive.VALID_BITS`, `archive.FULL_SCALE`
COUNTS_PER_PA = 10 ** (SENSITIVITY_DBFS / 20) * archive.FULL_SCALE / math.sqrt(2)  # RMS counts per Pa RMS
SELF_NOISE_DB_A = 94.0 - 65.0  # [ds] 65 dB(A) SNR re 94 dB SPL -> 29 dB(A) SPL equivalent input noise
BAND_HZ = (50.0, 15_000.0)  # [ds] usable band: 2nd-order roll-offs at both ends
# [estimate] `DECIMATION_HZ`: steep digital low-pass of the sigma-delta decimator
# [estimate] `DECIMATION_ORDER`: its steepness: amplitude 1 / (1 + (f / DECIMATION_HZ)^this)
# [estimate] `DC_OFFSET_COUNTS`: large DC offset (of 2**17), drifting from day to day
# [estimate] `DC_DRIFT_COUNTS`: the DC offset is set by the modulator's reference and drifts with
# temperature; 400 counts is 0.3 % of full scale (the datasheet gives no drift figure). It sits in the
# lowest Welch bins only, which the detrend removes.
# [ds] Sensitivity tolerance is +-1 dB between parts; a part's sensitivity moves far less with
# temperature (MEMS microphones: < 0.5 dB over -40..85 C). 0.5 dB is the day-to-day bound: each
# day's gain is drawn uniformly within +-GAIN_DRIFT_DB (a bound, not a standard deviation; a lab's
# few degrees between days would move it by hundredths of a dB, so the bound is generous).
GAIN_DRIFT_DB = 0.5
JUNK_BITS = 6  # [ds] 18 valid bits of the 24-bit word: bits 13..8 carry no information; bits 7..0 are zero

# --- proprioception ------------------------------------------------------------------------------
ANGLE_LSB_RAD = 2 * math.pi / 4096  # [cited] STS3215 datasheet: 12-bit magnetic encoder, 4096 steps per turn
# [estimate] `VELOCITY_NOISE_RAD_S`: the joints' velocity noise
CURRENT_LSB_A = 0.0065  # [cited] STS3215 memory table: the present-current register's unit, 6.5 mA
# [estimate] `CURRENT_NOISE_A`: PWM ripple
# [estimate] `IDLE_CURRENT_A`: a holding servo's draw
TORQUE_PER_AMP_NM = 0.7  # [cited] STS3215 datasheet: ~1.9 N m (19.5 kg cm) stall torque at ~2.7 A stall current, 7.4 V
# [estimate] `VISCOUS_NM_PER_RAD_S`: gear-train drag of a moving joint
# No day-to-day joint calibration drift: the STS3215 reads its angle from an absolute 12-bit
# magnetic encoder [FACTS], which has no offset to drift unless the horn or hand is reassembled,
# and the current reading has no documented offset drift (its 6.5 mA LSB and the PWM ripple
# above are the sensor's limits). Day-to-day differences reach the joints through the grasp.
# [estimate] Minsight force proxy: the closing stops when the estimate crosses 0.1 N, so its error
# shows as grasp force (`motion.finger_motion` stops on the estimate, the proxy records it). The
# force map of Insight, Minsight's parent design, is accurate to ~0.03 N in magnitude over 0.03-2 N
# across many contacts (Sun, Martius, Kuchenbecker, "A soft thumb-sized vision-based sensor with
# accurate all-round force perception", Nature Machine Intelligence 4, 2022); at one repeated
# contact near 0.1 N the error splits into frame-to-frame noise and a bias that holds for a day
# (the reference image is re-taken daily): 4 mN each (SD, `FORCE_NOISE_N` and `FORCE_BIAS_N`), a
# seventh of that figure apiece.
# [estimate] `FOLD_SPREAD`: the hanging fabric is folded by hand on the hanger: where the grasp lands
# the stack is two layers plus local slack and seams, +-10 % of its nominal thickness.
# [estimate] `CONTACT_OFFSET_MM`: where the contact centre lands on Minsight's shell: the grasp is
# force-controlled, not placed, so the patch wanders by about a third of its ~5 mm size between
# trials (SD, mm).

# --- the rig between sessions (`sim.rig`) ---------------------------------------------------------
# [cited] The lab's climate on a recording day. Building climate control holds 75 +- 2 F, i.e.
# 22.8-25.0 C, after ASHRAE's comfort guidance (ASHRAE Standard 55, "Thermal Environmental
# Conditions for Human Occupancy"), and indoor relative humidity within the comfort range 30-60 %
# (ASHRAE Standard 55-1992); each day draws both uniformly in these ranges (the cafe is an indoor
# room too). The climate is the same for every trial of a day.
ROOM_TEMPERATURE_C = (22.8, 25.0)
ROOM_HUMIDITY_PCT = (30.0, 60.0)  # [cited] ASHRAE Standard 55-1992
# [cited] Friction of a soft, hygroscopic contact against the climate: the in-vivo skin friction map
# of Klaassen et al. (Biotribology, 2016; reciprocating tribometer in a climate enclosure, 25-37 C,
# 40-80 % RH) grows with the product T x RH and doubles from 25 C / 40 % to 37 C / 80 %; Hendriks and
# Franklin ("Influence of surface roughness, material and climate conditions on the friction of
# human skin", Tribology Letters 37, 2010) likewise find friction twice as high in a humid climate
# (21-29 C, 37-92 % RH). Read as linear in T x RH, mu = a + b T RH with b / a = 1 / 960 (C %)^-1
# (a + 1000 b = 1, a + 2960 b = 2). The silicone fingertip is hydrophobic and only the cloth takes
# up water, so this skin figure is an upper estimate of the day-to-day change. The catalog's
# coefficients hold at the centre of the room's climate (`rig.friction_scale`).
FRICTION_CLIMATE_B_PER_A = 1.0 / 960.0
# [cited] The silicone's modulus against temperature: rubber elasticity is entropic, G = n k T
# (Treloar, "The Physics of Rubber Elasticity", 3rd ed., Oxford 1975), so the shells' stiffness
# scales with the absolute temperature: +0.34 % per K at room temperature. The catalog's and this
# file's stiffnesses hold at `SILICONE_REFERENCE_K` (the centre of the room's climate). Minsight's
# force map reads deformation, so a stiffer shell reads low: the closing stops later (`rig`).
CELSIUS_K = 273.15  # [law] 0 C in kelvin
SILICONE_REFERENCE_K = CELSIUS_K + sum(ROOM_TEMPERATURE_C) / 2
# [estimate] Cloth wear: rubbing teases loose fibre ends out of a staple-fibre fabric (the fuzz stage of
# pilling, Gintis and Mead, "The mechanism of pilling", Textile Research Journal 29, 1959; filament
# fabrics have no free ends, so fuzz-free cloth stays as it is). The Martindale pilling test
# (ISO 12945-2) assesses fuzz and pills after 125, 500, 1000 and 2000 rubs: the loose-fibre density
# is taken to grow linearly with the rubs a spot has had, doubling after `WEAR_DOUBLING_RUBS`, the
# middle of those stages (an estimate: the test grades pills, not a fibre density).
# A spot is rubbed in a trial when the grasp lands within a patch diameter (of `CONTACT_AREA_M2`) plus
# a stroke of it: a share (5 + 6) / (40 + 11) of the trials on the 40 mm grasp range, two passes a cycle.

# --- Minsight images --------------------------------------------------------------------------
# Sources: [minsight] Andrussow, Sun, Kuchenbecker, Martius, "Minsight: A Fingertip-Sized Vision-Based
# Tactile Sensor for Robotic Manipulation", Advanced Intelligent Systems 5(8), 2023, and its open
# design files and code (github.com/martius-lab/Minsight-sensor: CAD/skeleton.STEP, the calibration
# data Code/minsight_runner_ros/config/calibration_files/C1/indentation_info.txt, the camera node
# Code/.../minsight_sensor/camera.py); [insight] Sun, Kuchenbecker, Martius, "A soft thumb-sized
# vision-based sensor with accurate all-round force perception", Nature Machine Intelligence 4, 2022.
# Geometry, in millimetres: a cylinder capped by a hemisphere, the elastomer over-moulded on an
# aluminium skeleton; the camera sits on the axis in the base, the LED ring beside it.
SHELL_OUTER_RADIUS_MM = 11.8  # [minsight] radial distance of the calibration indentation points (indentation_info.txt)
SKELETON_RADIUS_MM = 10.25  # [minsight] outer radius of the skeleton (skeleton.STEP): the elastomer's inner face
SHELL_THICKNESS_MM = SHELL_OUTER_RADIUS_MM - SKELETON_RADIUS_MM  # 1.55 mm of elastomer
SHELL_WIDTH_MM = 2 * SHELL_OUTER_RADIUS_MM  # the fingertip's outer diameter (also Minsound's [paper: same dimensions])
SHELL_CYLINDER_MM = 15.0  # [minsight] skeleton length ~25 mm (skeleton.STEP) less the hemispherical cap's radius
# [minsight, camera.py] The camera delivers 1280x960; the node crops the central 960x960 and resizes it
# to 410x308 (W x H), so one square field of view spans both axes with different pixel pitches.
# [estimate] The lens is taken as an equidistant fisheye whose image circle fills the crop's width
# and reaches 80 degrees off axis (the wall ~1.8 mm above the camera): a wide-angle estimate, since
# the lens's field of view is not published.
CAMERA_HALF_FOV_RAD = math.radians(estimates.value("CAMERA_HALF_FOV_DEG"))
# [estimate] `LED_RING_RADIUS_MM`: the LED ring lies inside the 10.25 mm skeleton, around the camera
# [minsight] Full-colour SMD chip LEDs (Wuerth WL-SFCC) on a ring: red, green and blue emitters from
# three directions 120 degrees apart, the photometric-stereo lighting of [insight]: a tilt of the
# wall changes the three colours differently.
LED_ANGLES_RAD = (math.radians(90.0), math.radians(210.0), math.radians(330.0))  # red, green, blue
# [insight, minsight] A collimator in front of the LED ring shapes their light into a cone inside the
# shell ("structured light"). [minsight: NoContact_avg.png, the averaged no-contact reference] The
# whole image circle is lit, and the colours meet in zones with sharp edges ([insight]: contact "moves
# the elastomer from one colour zone to another"). [estimate] Each LED's light leaves within a cone
# about the axis wide enough to reach the wall next to the camera, its edge a penumbra of a few
# degrees (the collimator's drawing gives its aperture, not its optics): where one LED's cone ends
# on the far wall, the other colours remain, and that border is a colour zone's edge.
COLLIMATOR_HALF_ANGLE_RAD = math.radians(estimates.value("COLLIMATOR_HALF_ANGLE_DEG"))
COLLIMATOR_EDGE_RAD = math.radians(estimates.value("COLLIMATOR_EDGE_DEG"))
# [minsight: NoContact_avg.png, the mould insert's STL] The interior is moulded with radial ridges,
# about 30 around the circumference, running along the meridians: the reference image shows them as
# lines radiating from its centre (30 is read off that image; the STL would give the exact count, and
# one ridge more or less moves their period by 3 %). [estimate] Their relief, a tenth of a millimetre or so (a printed
# insert's features), tilts the wall to and fro, so each LED lights their flanks differently.
INTERIOR_RIDGES = 30
# [cited] The closed shell's aluminium-filled interior reflects much of the light it receives, and the
# reflections light the whole wall as in an integrating cavity: an evenly spread irradiance of
# rho / (1 - rho) times the wall's mean direct irradiance (the integrating sphere's multiplier;
# Goebel, "Generalized integrating-sphere theory", Applied Optics 6, 1967), which is what lights
# the reference image to its edge. [estimate] rho, the interior's diffuse reflectance:
# `INTERIOR_REFLECTANCE`. The ridges' relief: `INTERIOR_RIDGE_HEIGHT_MM`.
# [minsight: NoContact_avg.png] The camera's fixed exposure (camera.py: manual exposure 156, auto
# white balance off) shows the lit interior at mid-scale: the averaged reference's side-wall band
# reads ~135 DN. [estimate] The median pixel of the image circle's brightest channel sits at
# EXPOSURE_LEVEL_DN; pixels the LEDs light more strongly saturate at 255, as a fixed exposure does.
EXPOSURE_PERCENTILE = 50.0  # [numerics] where EXPOSURE_LEVEL_DN is given: the median
# [minsight] The interior is Ecoflex 00-30 filled with 65 um aluminium powder and 75 um aluminium
# flakes: a grainy metallic surface. [estimate] Each 75 um cell reflects a random share of the light
# (flake orientation): albedo 1 + FLAKE_CONTRAST * N(0, 1) per cell (estimate: half the cells' light
# is the diffuse powder, the flake half varies with unit coefficient of variation); a pixel shows the
# average over the cells in its footprint, so the grain fades with the pixel's area.
FLAKE_SIZE_MM = 0.075
# [estimate] Camera noise: shot noise of a small-pixel CMOS sensor, sigma = sqrt(DN / gain) with
# gain = full well / 255 electrons per DN (full well `CAMERA_FULL_WELL_E` ~6000 e-: order of magnitude
# for 1.4-2 um pixels); the node's bilinear resize to 410x308 blends 4 native pixels (noise x 2/3), and
# area-averaging a frame to a smaller size divides it by the square root of the pixels averaged.
RESIZE_NOISE_FACTOR = (
    2.0 / 3.0
)  # [minsight] camera.py's bilinear resize: sqrt(E[sum of squared bilinear weights]) = sqrt((2/3)^2)
# Contact mechanics. [cited] Hertz (1882): two equal elastic spheres (Minsight and the thumb's shell of
# the same size, the thin cloth between them) at force F touch over a disc of radius
# a = (3 F R_eff / (4 E*))^(1/3), R_eff = R / 2, 1 / E* = 2 (1 - nu^2) / E, and each shell is indented
# by a^2 / R. The displacement of the outer surface (Johnson, Contact Mechanics, 1985, eq. 3.41) reaches
# the inner wall through the layer with the kernel (1 + |k| d) e^(-|k| d): the displacement at depth d
# under a surface load of wavenumber k in an incompressible (nu = 0.5) elastic half-space (Johnson,
# Contact Mechanics, 1985, ch. 2: the Boussinesq solution's normal displacement,
# (2 (1 - nu) + k z) e^(-k z) / (2 (1 - nu))); about 0.6 of the indentation reaches the centre of
# the inner wall at 0.1 N. E from the Ecoflex 00-30 datasheet (Smooth-On): 100 % modulus 10 psi = 69 kPa,
# i.e. E = 3 * 69 kPa / (2 - 1/4) = 118 kPa for a neo-Hookean solid, nu = 0.5 (rubber). At 0.1 N:
# a = 1.8 mm, 0.27 mm per shell, consistent with SHELL_NORMAL_STIFFNESS_N_MM above.
ELASTOMER_E_PA = 3 * 69e3 / (2.0 - 0.25)
ELASTOMER_POISSON = 0.5  # [FACTS] rubber is incompressible
# [estimate] The skeleton holds the shell's global shape: the displacement vanishes one outer radius
# from the contact centre (the half-space's slow 1/r tail is cut there).
CONTACT_SUPPORT_MM = SHELL_OUTER_RADIUS_MM
# [estimate] Minsight's skeleton is an open cage of struts: between them the inner face is free, and
# a free face moves at least as the half-space's interior point at that depth and at most with the
# outer surface. INNER_FACE_FREE_GAIN scales the half-space's share (capped at all of it), and the
# shear the inner face keeps is an estimate of its own (a tangential load does not follow the
# normal kernel): INNER_SHEAR_SHARE of the skin's drag.
# [cited] The stroke rolls the contact: the fingertips are convex, and two spheres touch on the line
# of their centres, so offsetting the tips by +-x (the stroke) moves the contact along each shell by
# x 2R / (2R + t) over a stack of thickness t (geometry): +-3 mm for silk, +-2.5 mm for a 5 mm stack.
TRAVEL_STEP_MM = 0.25  # [numerics] the contact's fields are computed this far apart and interpolated
# The shear of the contact: the tangential load over the shell's shear stiffness
# (SHELL_SHEAR_STIFFNESS_N_MM above), spread like the indentation and along the rubbing, which runs
# across the finger (circumferentially on the shell).
# [paper] The grasp lands on the finger pad; the contact centre sits on the side wall where it meets
# the cap (axial position below, mm from the camera), wandering by CONTACT_OFFSET_MM between trials.
CONTACT_AXIAL_MM = SHELL_CYLINDER_MM
# [estimate] The fingers close on arcs about their joints: a stack thicker by t stops each finger t / 2
# earlier, which turns the contact along the shell by about R t / (2 L) (R the shell's 11.8 mm radius,
# L the 30-60 mm from the joint to the contact), towards the tip. Left out of the published simulator
# (0, the range's low end); the sensitivity study measures what it would change in the frames:
# `CONTACT_SHIFT_PER_STACK_MM`.
# [minsight, insight] Force accuracy: mean absolute force error 0.07 N (Minsight, over its surface),
# force magnitude accuracy ~0.03 N over 0.03-2 N (Insight); the image test checks that a step of
# this size is far above the camera noise for an ideal observer.
FORCE_ACCURACY_N = 0.03
# What the fabric stack changes in the image at a fixed 0.1 N (the force-controlled closing makes
# the force itself the same for every fabric):
# [cited] Patch size: a compressible stack between the shells acts as an elastic foundation
# (Johnson, Contact Mechanics, 1985, section 4.3: a thin compliant layer between curved bodies): the
# contact spreads to a ~ sqrt(2 R_eff (d_shell + d_stack)), the geometric overlap of the shells'
# indentation and the stack's give at 0.1 N (`compressibility x stack`), about 1.8 mm for silk and
# 5-6 mm for fleece or terry. At the same force the shell is indented less, as a flat punch's
# d = F / (2 a E*) (Johnson, eq. 3.36): the centre's depth falls as 1 / a. [cited] A bending-stiff
# stack bridges it like a plate on an elastic foundation, whose load spreads over (B / k)^(1/4)
# (Hetenyi 1946): the patch widens across the fold as the quarter power of the stack's bending stiffness.
# [estimate] Bending stiffness of a layer ~ E h^3 / 12, and its in-plane stiffness ~ E h, so relative
# to a reference layer B scales as stretch_stiffness * thickness^2 (reference: 5 N/mm, 0.5 mm, a
# shirting cotton, `BENDING_REF_STRETCH_N_MM`). Only stretch * thickness^2 of the reference enters:
# its thickness is where the estimated stiffness is given.
BENDING_REF_THICKNESS_MM = 0.5  # [numerics] the reference point BENDING_REF_STRETCH_N_MM is given at
# [estimate] The fold of the folded stack is a ridge (a U-turn of the cloth, about one stack thickness
# wide) that presses a line into the shell where it lies inside the patch. Through an elastic
# shell of thickness d, surface relief of wavelength lambda reaches the inner wall by the layer's
# kernel at k = 2 pi / lambda (the same law as the contact). The cloth's own weave or knit relief
# passes the same way (`minsight.texture_relief`): 14 % of a 2.8 mm corduroy wale, under 1 % at
# 1 mm, so only the coarse textures ripple the patch as the cloth slides.
# `RIDGE_WAVELENGTH_PER_THICKNESS`: a ridge of width w has its relief at lambda ~ 4 w
# `FOLD_ANGLE_SPREAD_RAD`: [paper: the hanger is moved between trials] the fold's direction varies
# The camera's day. [minsight, camera.py] Exposure and white balance are fixed by the camera node
# (manual exposure, auto white balance off), so they do not move between days; what moves is:
# * the LEDs' light with the room's temperature. [cited] Light output falls with junction temperature
#   as exp(-dT / T1): T1 ~ 95 K for AlGaInP (red), ~1600 K for GaInN (green, blue) (E. F. Schubert,
#   Light-Emitting Diodes, 2nd ed., Cambridge University Press 2006, ch. 6), so the red channel drifts
#   ~1 %/K and the frame's colour with it; the dominant-wavelength shift (< 0.1 nm/K) is negligible
#   against the camera's broad colour filters. The room's temperature is the day's climate
#   (`ROOM_TEMPERATURE_C`, section "the rig between sessions"), relative to its centre.
LED_T1_K = (95.0, 1600.0, 1600.0)
# * the LEDs' drive: [cited] series-resistor LEDs on the USB supply; the current follows (V - Vf) / R,
#   Vf ~2.0 V (red) and ~3.0 V (green, blue) (full-colour chip LED datasheets). The USB 2.0
#   specification's 4.75-5.25 V bounds every host and load; [estimate] one port of the one host the
#   rig uses moves by tens of millivolts between days (`USB_VBUS_DAY_SPREAD_V`, uniform either way).
USB_VBUS_V = 5.0  # [cited] USB 2.0 specification, nominal
LED_FORWARD_V = (2.0, 3.0, 3.0)  # [cited] full-colour chip LED datasheets, as above
# Not a day term: the seating of the shell on the base. [minsight] The elastomer is over-moulded on
# its skeleton, and the paper never remounts it, so where it sits is the device's, one draw:
# [estimate] SLA-printed mating parts (the camera holder and base are Form 3 prints [minsight]) fit
# to ~0.1 mm (Formlabs' tolerance guide), so it sits up to ~0.05 mm higher or lower (SD,
# `SEATING_AXIAL_SD_MM`) and turned about its axis by that much over its 10 mm radius.
SEATING_ROTATION_SD_RAD = estimates.value("SEATING_AXIAL_SD_MM") / SKELETON_RADIUS_MM
# * the reference (no-contact) frames are taken anew each session and averaged
#   (`archive.REFERENCE_FRAMES`), so the reference carries that day's LEDs, and a thirtieth of one
#   frame's noise variance.
# [numerics] Frames smaller than 308x410 are rendered at RENDER_SUPERSAMPLE times their size (at most the full
# 308x410) from the same millimetre scene and area-averaged down, as the paper downsamples.
RENDER_SUPERSAMPLE = 2
# [estimate] joint angles of the open hand: thumb (3 joints), middle finger (2), palm (1)
OPEN_POSE_RAD = (
    estimates.value("OPEN_POSE_THUMB1_RAD"),
    estimates.value("OPEN_POSE_THUMB2_RAD"),
    estimates.value("OPEN_POSE_THUMB3_RAD"),
    estimates.value("OPEN_POSE_MIDDLE1_RAD"),
    estimates.value("OPEN_POSE_MIDDLE2_RAD"),
    estimates.value("OPEN_POSE_PALM_RAD"),
)
# How each finger's closing travel splits over its joints: the base joints rub and the palm holds
# still (0), the middle finger closes with its second joint alone (1), the thumb splits its travel
# between its second and third joints [estimate] [numerics: the zeros and ones are the model's
# structure, not magnitudes].
_THUMB2 = estimates.value("CLOSING_SHARE_THUMB2")
CLOSING_SHARE = (0.0, _THUMB2, 1.0 - _THUMB2, 0.0, 1.0, 0.0)
# [estimate] `PALM_REACTION_SHARE`: the palm joint holds still but takes this share of the rubbing
# joints' tangential load torque (the hand's reaction to the strokes); the ISyHand's kinematics are
# unpublished.
# [estimate] `SERVO_STIFFNESS_NM_RAD`: position-loop stiffness: loaded joints lag their command
# [estimate] `READ_LATENCY_S`: joints are read just before the frame is captured
