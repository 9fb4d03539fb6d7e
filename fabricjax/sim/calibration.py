"""Every physical constant of the scene simulator, in one place, with where it comes from.

Calibration is by physical parameters only: levels, SNRs and bands from the paper and the
SPH0645 datasheet, geometry and material constants as textbook-order estimates. Nothing here was
tuned to a classification accuracy. Sources are marked, here and in the modules' docstrings
("[paper, Section]" names where, "[paper: ...]" what it says):

    [paper]  stated in the paper (arxiv_main.tex, Method / Experiments)
    [ds]     SPH0645LM4H datasheet (Knowles): -26 dBFS at 94 dB SPL, 65 dB(A) SNR, AOP 120 dB SPL,
             18 valid bits of a 24-bit word in a 32-bit I2S slot, usable band 50 Hz-15 kHz
    [phys]   a physical law or a material/geometry estimate (order of magnitude, stated)
    [hw]     STS3215 servo / robot-hand estimates (resolution of the registers, lever lengths)
    [FACTS]  an established property of the phenomenon from outside the paper and the datasheet
             (texture vibration f = v / lambda, babble spectra, MEMS DC offset, magnetic encoders),
             stated where it is used
"""

from __future__ import annotations

import math

from fabricjax import archive

# --- time base --------------------------------------------------------------------------------
# [paper] The audio sample rate (48 kHz), the step rate (50 Hz, one step per Minsight frame) and the
# audio samples per step (2048) are the archive format's: `archive.AUDIO_RATE`, `STEP_RATE`, `WINDOW`.
LEAD_IN = 4096  # samples recorded before the procedure starts (>= archive.WINDOW so every window is full)
FRAME_JITTER_S = 0.0008  # [hw] USB camera frame-time jitter: a UVC camera delivers frames on its own
# clock; the host timestamps them at USB transfer with ~1 ms scheduling jitter (a USB 2.0 microframe
# is 125 us; Linux user-space wake-up latency is ~0.1-1 ms), hence +-0.8 ms
CONTROL_HZ = 2000  # grid on which the finger motion is integrated (then interpolated to 48 kHz)

# --- finger motion [paper: force-controlled closing until 0.1 N, then rubbing cycles] ---------
GRASP_FORCE_N = 0.1  # [paper] closing stops when Minsight's force estimate reaches this
OPEN_GAP_MM = 14.0  # [hw] fingertip gap of the open pose
CLOSING_SPEED_MM_S = 20.0  # [hw] relative fingertip closing speed (same for every fabric [paper])
SHELL_NORMAL_STIFFNESS_N_MM = 0.25  # [phys] two soft silicone shells in series, normal direction
SHELL_SHEAR_STIFFNESS_N_MM = 0.30  # [phys] shear stiffness of one shell at the contact
SETTLE_S = 0.1  # pause between the grasp and the first rubbing stroke
STOP_S = 0.1  # recording continues briefly after the last stroke
RUB_AMPLITUDE_MM = 3.0  # [hw] each fingertip moves +-3 mm laterally, the two in opposite phase
CYCLE_HZ = 2.0  # [hw] commanded rubbing frequency: 50 cycles ~ 25 s before the load droop
ARC_MM = 0.15  # [phys] extra indentation at the stroke ends (the fingertips move on arcs)
FINGER_LEVER_MM = 60.0  # [hw] joint axis to fingertip contact
# [paper: "the fingers move more slowly when finger-fabric friction is high"] Position-controlled
# hobby servos lose speed under load: speed = commanded / (1 + SPEED_DROOP_PER_N * mu * F_n).
# 2 / N gives ~6 % (mu = 0.25) to ~22 % (mu = 0.95) slower cycles at 0.1-0.15 N: trials of ~1300-1550 steps.
SPEED_DROOP_PER_N = 2.0
# [hw] An STS3215's no-load speed is proportional to its supply voltage (datasheet: 0.222 s/60 deg at
# 7.4 V, 0.16 s/60 deg at 12 V, i.e. ~6 %/V); a bench supply under a varying load sags by ~0.1-0.2 V:
# a per-trial spread of ~2 % of the rubbing rate.
SPEED_JITTER = 0.02
CYCLE_PHASE_JITTER = 0.01  # [hw] slow wander of the stroke rate within a trial: half the per-trial spread
# [phys] The hanging cloth creeps between strokes (random walk): a stroke's net slip is the
# stick length mu F_n / k_t ~ 0.1-0.3 mm; about a third of it is not recovered on the way back.
CLOTH_CREEP_MM_PER_CYCLE = 0.05

# --- fabric surface [FACTS: f = v / lambda; roughness spectrum 1/f^s; fuzz] -----------------------
PROFILE_DX_MM = 0.001  # 1 um grid: resolves content to > 20 kHz at the fastest slide speed
PROFILE_LEN_MM = 65.536  # one cloth strip per fabric (2**16 samples); grasps land anywhere on it
# [paper: "after each trial, the position of the clothes hanger was adjusted to create variation
# in the grasping location"] The grasp lands anywhere on the strip, at least one contact length
# (~10 mm) from its ends: independent cloth for every trial, so no two trials share a surface.
GRASP_RANGE_MM = (12.0, 52.0)
ROUGHNESS_K_MIN = 0.5  # cycles/mm: below (2 mm wavelengths) the fabric drapes rather than vibrates
WEAVE_SHARE = 0.5  # fraction of the RMS height in the periodic weave (the rest: random roughness)
WEAVE_HARMONICS = 8
WEAVE_IRREGULARITY = 0.03  # [phys] yarn spacing varies by ~3 % of the period (woven-fabric CV of yarn spacing, a few %)
LOCAL_ROUGHNESS_SPREAD = 0.2  # [phys] local roughness varies +-20 % along the strip (10 mm correlation): wear, creases, pile direction
FUZZ_FIBRES_PER_MM = 6.0  # loose fibre ends per mm of path at fuzz = 1
FUZZ_FIBRE_WIDTH_MM = 0.008  # [phys] fibre diameter ~10-20 um
FUZZ_HEIGHT = 0.6  # fibre bump height relative to the fabric's RMS roughness
SHELL_ROUGHNESS_UM = 0.5  # [phys] the silicone skin's own micro-texture: all class 0 rubs against
SHELL_SPECTRAL_SLOPE = 2.0

# --- contact sound in the Minsound cavity ---------------------------------------------------------
# [phys] Adiabatic cavity: p = gamma * P0 * dV / V. The fabric profile displaces the outer skin;
# a fraction of that reaches the inner wall through ~3 mm of silicone over the contact patch.
GAMMA_P0_PA = 1.4 * 101_325.0
CONTACT_AREA_M2 = 20e-6  # ~5 mm x 4 mm contact patch at 0.1 N
WALL_COUPLING = 0.01  # inner-wall displacement per outer-surface displacement
CAVITY_VOLUME_M3 = 8e-6  # ~8 cm^3 of air inside the shell
TEXTURE_PA_PER_UM = GAMMA_P0_PA * CONTACT_AREA_M2 * WALL_COUPLING * 1e-6 / CAVITY_VOLUME_M3  # ~3.5e-3
# Shell wall: mass-spring wall mode with viscoelastic losses (silicone damping rises with f).
SHELL_MODE_HZ = 3000.0
SHELL_MODE_Q = 1.5
SHELL_LOSS_HZ = 12000.0  # exp(-f / SHELL_LOSS_HZ) extra viscoelastic loss
# Stick-slip: micro-slips per mm slid grow with friction; each releases energy at asperity scale
# (amplitude ~ mu * F_n * asperity height), plus one larger release at every stroke reversal
# (elastic energy 1/2 k delta^2 stored in the stuck shell and stretched cloth).
SLIPS_PER_MM = 6.0  # at mu = 1
SLIP_PA = 0.06  # click peak pressure at mu * F_n = 0.05 N and 20 um asperities
SLIP_REF_FORCE_N = 0.05
SLIP_REF_ROUGHNESS_UM = 20.0
RELEASE_PA = 0.15  # reversal release at delta = 0.1 mm, mu * F_n = 0.05 N, 20 um asperities
SLIP_RING_HZ = (900.0, 3500.0)  # contact/skin ring of a slip click
SLIP_DECAY_S = 0.0003
SLIP_SPREAD = 0.5  # log-normal sigma of click amplitudes

# --- air paths --------------------------------------------------------------------------------
# [phys] The palm microphone (~8 cm away, in free air) hears what the fabric and fingertips radiate:
# a small radiator (fingertip plus the rubbed patch of hanging cloth) is ~f^1 below its radiation
# corner; the closed-cavity pressure is ~30 dB above the free-field pressure ~8 cm away (rubbing
# cloth near the ear is faintly audible, tens of dB SPL).
AIR_PATH_GAIN_DB = -30.0  # palm pressure relative to cavity pressure, above the corner
AIR_PATH_CORNER_HZ = 500.0
PALM_DISTANCE_M = 0.08  # [paper, hw] contact to the microphone "on the side of the palm": ~8 cm
SOUND_SPEED_M_S = 343.0  # [phys] air at 20 C
# How loud the rubbing is at the palm against the room (measured on this simulator by
# `python -m experiments.palm_physics`, results/palm_physics.md; magnitudes and sources here):
# * The fingertip's own radiation is bounded by physics [phys]: incompressible silicone makes the
#   shell's outer volume change equal the cavity's, so the fingertip is a pulsating sphere
#   (`air_path.fingertip_radiation`): k^2 V / (4 pi r) = -52 dB re the cavity pressure at 1 kHz and
#   8 cm, +12 dB per octave up to ka = 1 (3.6 kHz for the 30 mm shell). After the shell's wall mode
#   it peaks near -33 dB at 3 kHz and is < -39 dB below 2 kHz or above 6 kHz. The lumped -30 dB
#   path exceeds it at every frequency (tested): the rest is the rubbed cloth, whose radiation
#   (a porous, floppy membrane far below its coincidence frequency) no source pins down better
#   than the estimate above, so it stays.
# * What comes out: rubbing ~6-42 dB(A) at the palm depending on the fabric (smooth satins and
#   silks at the bottom, knits and piles at the top), against the lab room's 29-31 dB(A) [paper],
#   the SPH0645's own 29 dB(A) [ds] and the servos' ~30 dB(A) (below): about half the classes rise
#   above the rest in some octave band in the lab. The cafe room (47-55 dB(A) [paper]) is babble
#   [FACTS: long-term speech spectrum, peak 125-250 Hz], ~20-30 dB above the lab below 1 kHz but
#   only ~2-7 dB above it at 4-8 kHz, so in the cafe the palm hears the room, not the rubbing,
#   except a few dB of the roughest fabrics at 4-8 kHz. The paper reports no palm-side level of
#   the rubbing; its palm-only row (59 % test) says the lab palm does hear many fabrics.
# * Day or fabric: between lab days the palm's level moves with the room (drawn within `LAB_DB_A`
#   [paper]: SD 0.6 dB) and the microphone's gain (within +-`GAIN_DRIFT_DB` [ds]: SD 0.3 dB); the
#   rubbing moves it by ~3 dB(A) SD between classes, so the fabric, not the day, explains most
#   (~80-98 %) of the palm's per-trial octave-band level variance in the lab, the day a few %.
#   Lab to cafe is the large change: +20 dB(A), nearly all of it below 2 kHz.
# [phys] Mass law for the shell wall: TL = 20 log10(f * m'') - 47 dB, m'' = 1100 kg/m^3 * 2 mm
# (a thin shell: Minsight's must deform visibly at 0.1 N).
SHELL_SURFACE_MASS_KG_M2 = 2.2
SHELL_TL_MIN_DB = 3.0  # leaks around the base and the stiffness-controlled region at low frequency
SHELL_TL_MAX_DB = 40.0  # flanking through the aluminium skeleton

# --- servo noise (heard by both microphones, also in class 0) ---------------------------------------
GEAR_RATIO = 345.0  # [hw] STS3215
GEAR_TEETH = 10  # first-stage pinion: mesh frequency = motor rev/s * teeth
SERVO_TONE_PA = 0.006  # gear-mesh tone at 1 rad/s joint speed, as heard inside the shell (~50 dB)
SERVO_BROADBAND_PA = 0.004  # motor/gear broadband noise at 1 rad/s
SERVO_HOLD_PA = 0.001  # holding servos' PWM hum (always present, ~34 dB)
SERVO_LOAD_REF_NM = 0.01  # torque at which the gear noise doubles
SERVO_STRUCTURE_BAND_HZ = (150.0, 6000.0)  # structure-borne band into the Minsound cavity
SERVO_PALM_GAIN_DB = -10.0  # airborne at the palm (the servos sit in the palm) vs structure-borne

# --- ambient sound [paper: lab 29-31 dB, cafe 47-55 dB at the external mic; FACTS: babble] --------
LAB_DB_A = (29.0, 31.0)
CAFE_DB_A = (47.0, 55.0)
CAFE_DAY_SPREAD_DB = 2.0  # a cafe day sits at U(48, 54), each trial +-1 dB, all within 47-55
BABBLE_PEAK_HZ = 180.0  # long-term speech spectrum of many talkers peaks near 125-250 Hz
BABBLE_MODULATION = 0.25  # residual syllabic modulation of many overlapping talkers
CLATTER_PER_S = 1.5  # cups, plates, cutlery
CLATTER_RING_HZ = (2000.0, 7000.0)
CLATTER_DECAY_S = 0.015
CLATTER_PEAK_DB = 12.0  # clatter peaks above the babble RMS

# --- SPH0645 [ds] -------------------------------------------------------------------------------
SENSITIVITY_DBFS = -26.0  # at 94 dB SPL (1 Pa)
# 18 valid bits, full scale 2**17: `archive.VALID_BITS`, `archive.FULL_SCALE`
COUNTS_PER_PA = 10 ** (SENSITIVITY_DBFS / 20) * archive.FULL_SCALE / math.sqrt(2)  # RMS counts per Pa RMS
SELF_NOISE_DB_A = 94.0 - 65.0  # 65 dB(A) SNR re 94 dB SPL -> 29 dB(A) SPL equivalent input noise
BAND_HZ = (50.0, 15_000.0)  # [ds] usable band: 2nd-order roll-offs at both ends
DECIMATION_HZ = 21_000.0  # steep digital low-pass of the sigma-delta decimator
DC_OFFSET_COUNTS = -3000.0  # [ds, FACTS] large DC offset (of 2**17), drifting from day to day
# [ds, FACTS] The DC offset is set by the modulator's reference and drifts with temperature; 400
# counts is 0.3 % of full scale (an estimate: the datasheet gives no drift figure). It sits in the
# lowest Welch bins only, which the detrend removes.
DC_DRIFT_COUNTS = 400.0
# [ds] Sensitivity tolerance is +-1 dB between parts; a part's sensitivity moves far less with
# temperature (MEMS microphones: < 0.5 dB over -40..85 C). 0.5 dB is the day-to-day bound: each
# day's gain is drawn uniformly within +-GAIN_DRIFT_DB (a bound, not a standard deviation; a lab's
# few degrees between days would move it by hundredths of a dB, so the bound is generous).
GAIN_DRIFT_DB = 0.5
JUNK_BITS = 6  # bits 13..8 of the 24-bit word carry no information; bits 7..0 are zero

# --- proprioception [hw] ----------------------------------------------------------------------
ANGLE_LSB_RAD = 2 * math.pi / 4096  # STS3215 position register
VELOCITY_NOISE_RAD_S = 0.02
CURRENT_LSB_A = 0.0065  # STS3215 present-current unit
CURRENT_NOISE_A = 0.006  # PWM ripple
IDLE_CURRENT_A = 0.04
TORQUE_PER_AMP_NM = 0.7  # ~1.9 N m stall at ~2.7 A
VISCOUS_NM_PER_RAD_S = 0.01  # gear-train drag of a moving joint
# No day-to-day joint calibration drift: the STS3215 reads its angle from an absolute 12-bit
# magnetic encoder [FACTS], which has no offset to drift unless the horn or hand is reassembled,
# and the current reading has no documented offset drift (its 6.5 mA LSB and the PWM ripple
# above are the sensor's limits). Day-to-day differences reach the joints through the grasp.
# [phys] Minsight force proxy: the closing stops when the estimate crosses 0.1 N, so its error
# shows as grasp force (`motion.finger_motion` stops on the estimate, the proxy records it). The
# force map of Insight, Minsight's parent design, is accurate to ~0.03 N in magnitude over 0.03-2 N
# across many contacts (Sun, Martius, Kuchenbecker, "A soft thumb-sized vision-based sensor with
# accurate all-round force perception", Nature Machine Intelligence 4, 2022); at one repeated
# contact near 0.1 N the error splits into frame-to-frame noise and a bias that holds for a day
# (the reference image is re-taken daily): 4 mN each (SD), a seventh of that figure apiece.
FORCE_NOISE_N = 0.004
FORCE_BIAS_N = 0.004
# [phys] The hanging fabric is folded by hand on the hanger: where the grasp lands the stack is
# two layers plus local slack and seams, +-10 % of its nominal thickness.
FOLD_SPREAD = 0.1
# [phys] Where the contact centre lands on Minsight's shell: the grasp is force-controlled, not
# placed, so the patch wanders by about a third of its ~5 mm size between trials (SD, mm).
CONTACT_OFFSET_MM = 1.5

# --- the rig between sessions (`sim.rig`) ---------------------------------------------------------
# [phys] The lab's climate on a recording day. Building climate control holds 75 +- 2 F, i.e.
# 22.8-25.0 C, after ASHRAE's comfort guidance (ASHRAE Standard 55, "Thermal Environmental
# Conditions for Human Occupancy"), and indoor relative humidity within the comfort range 30-60 %
# (ASHRAE Standard 55-1992); each day draws both uniformly in these ranges (the cafe is an indoor
# room too). The climate is the same for every trial of a day.
ROOM_TEMPERATURE_C = (22.8, 25.0)
ROOM_HUMIDITY_PCT = (30.0, 60.0)
# [phys] Friction of a soft, hygroscopic contact against the climate: the in-vivo skin friction map
# of Klaassen et al. (Biotribology, 2016; reciprocating tribometer in a climate enclosure, 25-37 C,
# 40-80 % RH) grows with the product T x RH and doubles from 25 C / 40 % to 37 C / 80 %; Hendriks and
# Franklin ("Influence of surface roughness, material and climate conditions on the friction of
# human skin", Tribology Letters 37, 2010) likewise find friction twice as high in a humid climate
# (21-29 C, 37-92 % RH). Read as linear in T x RH, mu = a + b T RH with b / a = 1 / 960 (C %)^-1
# (a + 1000 b = 1, a + 2960 b = 2). The silicone fingertip is hydrophobic and only the cloth takes
# up water, so this skin figure is an upper estimate of the day-to-day change. The catalog's
# coefficients hold at the centre of the room's climate (`rig.friction_scale`).
FRICTION_CLIMATE_B_PER_A = 1.0 / 960.0
# [phys] The silicone's modulus against temperature: rubber elasticity is entropic, G = n k T
# (Treloar, "The Physics of Rubber Elasticity", 3rd ed., Oxford 1975), so the shells' stiffness
# scales with the absolute temperature: +0.34 % per K at room temperature. The catalog's and this
# file's stiffnesses hold at `SILICONE_REFERENCE_K` (the centre of the room's climate). Minsight's
# force map reads deformation, so a stiffer shell reads low: the closing stops later (`rig`).
CELSIUS_K = 273.15
SILICONE_REFERENCE_K = CELSIUS_K + sum(ROOM_TEMPERATURE_C) / 2
# [phys] Cloth wear: rubbing teases loose fibre ends out of a staple-fibre fabric (the fuzz stage of
# pilling, Gintis and Mead, "The mechanism of pilling", Textile Research Journal 29, 1959; filament
# fabrics have no free ends, so fuzz-free cloth stays as it is). The Martindale pilling test
# (ISO 12945-2) assesses fuzz and pills after 125, 500, 1000 and 2000 rubs: the loose-fibre density
# is taken to grow linearly with the rubs a spot has had, doubling after `WEAR_DOUBLING_RUBS`, the
# middle of those stages (an estimate: the test grades pills, not a fibre density).
# A spot is rubbed in a trial when the grasp lands within a patch diameter (of `CONTACT_AREA_M2`) plus
# a stroke of it: a share (5 + 6) / (40 + 11) of the trials on the 40 mm grasp range, two passes a cycle.
WEAR_DOUBLING_RUBS = 1000.0

# --- Minsight images --------------------------------------------------------------------------
SHELL_WIDTH_MM = 30.0  # the 410-pixel image spans ~30 mm of shell interior
INDENT_PX_PER_N = 40.0  # radial bulge at full resolution per N of normal force
SHEAR_PX_PER_N = 90.0  # lateral shift at full resolution per N of tangential force
CONTACT_SIGMA_PX = 55.0  # contact patch radius at full resolution, 0.1 N, thin fabric
# What the fabric stack changes in the image at a fixed 0.1 N (the force-controlled closing makes
# the force itself the same for every fabric):
# [phys] Patch size: a compressible stack conforms to the fingertip and spreads the load (the
# patch grows ~15 % per mm of compressible stack), and a bending-stiff stack bridges it like a
# plate on an elastic foundation, whose load spreads over (B / k)^(1/4) (Hetenyi 1946): the patch
# widens across the fold as the quarter power of the stack's bending stiffness.
CONFORM_PER_MM = 0.15
# [phys] Bending stiffness of a layer ~ E h^3 / 12, and its in-plane stiffness ~ E h, so relative
# to a reference layer B scales as stretch_stiffness * thickness^2 (reference: 5 N/mm, 0.5 mm, a
# shirting cotton).
BENDING_REF_STRETCH_N_MM = 5.0
BENDING_REF_THICKNESS_MM = 0.5
# [phys] The fold of the folded stack is a ridge (a U-turn of the cloth, about one stack thickness
# wide) that presses a line into the shell where it lies inside the patch. Through an elastic
# shell of thickness d, surface relief of wavelength lambda reaches the inner wall attenuated by
# exp(-2 pi d / lambda) (Boussinesq layer solution, decay of a periodic surface load); the same
# law removes weave textures of sub-millimetre period entirely, so none is drawn.
SHELL_THICKNESS_MM = 2.0  # estimate for Minsight's elastomer shell (a few mm; exact value not public)
RIDGE_WAVELENGTH_PER_THICKNESS = 4.0  # a ridge of width w has its relief at lambda ~ 4 w
FOLD_ANGLE_SPREAD_RAD = 0.3  # [paper: the hanger is moved between trials] the fold's direction varies
SHADING_PER_N = 1.2  # darkening of the indented region per N
CAMERA_NOISE = 1.5  # grey levels
OPEN_POSE_RAD = (0.30, 0.20, 0.10, 0.00, 0.20, 0.50)  # [hw] joint angles of the open hand
CLOSING_SHARE = (0.0, 0.6, 0.4, 0.0, 1.0, 0.0)  # how each finger's closing travel splits over joints
SERVO_STIFFNESS_NM_RAD = 4.0  # [hw] position-loop stiffness: loaded joints lag their command
READ_LATENCY_S = 0.002  # joints are read just before the frame is captured
