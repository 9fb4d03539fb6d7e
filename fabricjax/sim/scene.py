"""A scene: which trial to simulate, which effects it calls for, which streams it wants.

Randomness is derived, never shared: every effect draws from its own generator, seeded by
`numpy.random.SeedSequence` from the scene's seed, the effect's name and the scope the draw
belongs to. Scopes fix what varies together:

    hardware  the same robot every day (shell texture, servo signature)
    fabric    the same cloth every day (its surface profile; its wear follows `Scene.history`)
    day       one recording day: ambient level, microphone DC offset and gain, force-proxy bias,
              the room's temperature and humidity
    trial     one trial: grasp position, fold, speed, jitter

So leaving an effect out never changes another effect's draws, and two trials of one day share
that day's drift (the nuisance the paper's day-based splits are meant to expose).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import zlib
from typing import Any

import numpy as np

from fabricjax import catalog, source
from fabricjax.sim import calibration as cal
from fabricjax.sim import estimates, rig
from fabricjax.store import archive

EFFECTS = (
    "texture",
    "stick_slip",
    "shell",
    "air_path",
    "servo_noise",
    "ambient",
    "sph0645",
    "proprioception",
    "climate",
    "wear",
)
"""Optional physics. The finger motion (the procedure itself) always runs."""
STREAMS = ("audio", "proprio", "images")
REQUIRED_STREAMS = ("audio", "proprio")  # the archive format requires audio, joints and force
SCOPES = ("hardware", "fabric", "day", "trial")


def magnitudes(besides: str | None = None) -> str:
    """A short hash of every constant of `calibration` as it holds now (all but `besides`): part
    of every simulated scene, so data simulated with other magnitudes is simulated again."""
    values = {k: v for k, v in sorted(vars(cal).items()) if k.isupper() and k != besides}
    return hashlib.sha256(json.dumps(values, default=repr).encode()).hexdigest()[:12]  # [numerics] 12 hex digits


# Taken when this module is imported, before any scene's estimates are put in force (`trial.use_estimates`).
MAGNITUDES = magnitudes()


# The catalog's physical parameters are our textbook-order choices: each kind is scaled, for every
# fabric alike, by an estimate of the registry (1 in the published data: the catalog as it is).
CATALOG_SCALES = {
    "weave_period_mm": "CATALOG_WEAVE_PERIOD_SCALE",
    "roughness_um": "CATALOG_ROUGHNESS_SCALE",
    "friction": "CATALOG_FRICTION_SCALE",
    "thickness_mm": "CATALOG_THICKNESS_SCALE",
    "compressibility": "CATALOG_COMPRESSIBILITY_SCALE",
    "stretch_stiffness": "CATALOG_STRETCH_STIFFNESS_SCALE",
    "fuzz": "CATALOG_FUZZ_SCALE",
}


def simulated_fabric(fabric_id: int) -> catalog.Fabric:
    """The catalog's fabric as the simulator uses it: each physical parameter kind times its
    catalog scale (`CATALOG_SCALES`); the catalog's own entry where every scale is 1, and for
    class 0 (no fabric: the fingers rub each other)."""
    fab = catalog.fabric(fabric_id)
    scales = {field: getattr(cal, name) for field, name in CATALOG_SCALES.items()}
    if not fab.is_fabric or all(s == 1.0 for s in scales.values()):
        return fab
    return dataclasses.replace(fab, **{field: getattr(fab, field) * s for field, s in scales.items()})


@dataclasses.dataclass(frozen=True)
class Scene:
    fabric_id: int
    day: int = 1
    trial: int = 0
    condition: str = "lab"
    effects: tuple[str, ...] = EFFECTS
    streams: tuple[str, ...] = REQUIRED_STREAMS
    image_size: tuple[int, int] = archive.MINSIGHT_SIZE
    cycles: int = cal.CYCLES_PER_TRIAL
    seed: int = 0
    history: int = 0  # trials this fabric's cloth went through before this one (its wear)
    # estimates set away from the registry's values (`sim.estimates`), sorted (name, value) pairs:
    # the sensitivity study's and the calibration's points; () is the simulator as published
    estimates: tuple[tuple[str, float], ...] = ()

    def __post_init__(self):
        catalog.fabric(self.fabric_id)
        if self.condition not in archive.CONDITIONS:
            raise ValueError(f"condition must be one of {archive.CONDITIONS}, got {self.condition!r}")
        bad = [e for e in self.effects if e not in EFFECTS]
        if bad:
            raise ValueError(f"unknown effects {bad}; known: {EFFECTS}")
        bad = [s for s in self.streams if s not in STREAMS]
        if bad:
            raise ValueError(f"unknown streams {bad}; known: {STREAMS}")
        missing = [s for s in REQUIRED_STREAMS if s not in self.streams]
        if missing:
            raise ValueError(f"streams {missing} are required by the archive format (audio, joints, force)")
        if self.history < 0:
            raise ValueError(f"history counts earlier trials: need >= 0, got {self.history}")
        checked = estimates.check(dict(self.estimates))
        if tuple(sorted(checked.items())) != tuple(self.estimates):
            raise ValueError(f"estimates must be sorted (name, value) pairs, each name once, got {self.estimates}")
        if self.cycles < 1 or min(self.image_size) < 8:  # [numerics] the smallest frame the renderer supports
            raise ValueError(f"need cycles >= 1 and images of at least 8x8, got {self.cycles}, {self.image_size}")

    @property
    def fabric(self) -> catalog.Fabric:
        return simulated_fabric(self.fabric_id)

    def wants(self, name: str) -> bool:
        """True when the scene calls for effect or stream `name`."""
        return name in self.effects or name in self.streams

    def to_json(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["estimates"] = dict(self.estimates)
        if not d["estimates"]:
            del d["estimates"]  # the published simulator: its archives' scenes name no estimates
        return {
            **{k: list(v) if isinstance(v, tuple) else v for k, v in d.items()},
            # the code that simulates it (`source.simulator`): an archive that other code made is
            # simulated again (`dataset.is_done`)
            "simulator": source.simulator()[:16],  # as results name fingerprints [numerics]
            "magnitudes": MAGNITUDES,
        }

    def rng(self, name: str, scope: str) -> np.random.Generator:
        """The generator of draw `name` at `scope` (see the module docstring)."""
        keys = {
            "hardware": (),
            "fabric": (self.fabric_id,),
            "day": (self.day, archive.CONDITIONS.index(self.condition)),
            "trial": (self.fabric_id, self.day, self.trial, archive.CONDITIONS.index(self.condition)),
        }[scope]
        entropy = [self.seed, SCOPES.index(scope), zlib.crc32(name.encode()), *keys]
        return np.random.default_rng(np.random.SeedSequence(entropy))


@dataclasses.dataclass(frozen=True)
class Nuisance:
    """What changes between days and trials without changing the fabric."""

    ambient_db_a: float  # at the palm microphone
    mic_gain_db: np.ndarray  # (2,)
    mic_dc_counts: np.ndarray  # (2,)
    force_bias_n: float
    grasp_mm: float  # where on the cloth strip the fingertips land
    fold: float  # thickness factor of the folded stack
    speed: float  # servo speed factor
    frame_phase_s: float  # when the first camera frame falls relative to the procedure start
    contact_offset_mm: np.ndarray  # (2,) offset of the contact centre on the Minsight shell
    temperature_c: float | None  # the room's, per day (None: "climate" not called for)
    humidity_pct: float | None
    friction_scale: float  # friction relative to the catalog's (1 without "climate")
    silicone_scale: float  # the shells' stiffness relative to nominal (1 without "climate")
    fuzz_scale: float  # the cloth's loose-fibre density relative to new (1 without "wear")


def nuisance(scene: Scene) -> Nuisance:
    """The scene's day and trial draws, and what the rig's state ("climate", "wear") makes of them."""
    day = scene.rng("nuisance", "day")
    trial = scene.rng("nuisance", "trial")
    climate = rig.climate(scene.rng("climate", "day")) if scene.wants("climate") else (None, None)
    if scene.condition == "lab":
        level = day.uniform(*cal.LAB_DB_A)
        level = float(np.clip(level + trial.uniform(-cal.LAB_TRIAL_JITTER_DB, cal.LAB_TRIAL_JITTER_DB), *cal.LAB_DB_A))
    else:
        lo, hi = cal.CAFE_DB_A
        level = day.uniform(lo + cal.CAFE_DAY_SPREAD_DB / 2, hi - cal.CAFE_DAY_SPREAD_DB / 2)
        level = float(np.clip(level + trial.uniform(-cal.CAFE_TRIAL_JITTER_DB, cal.CAFE_TRIAL_JITTER_DB), lo, hi))
    return Nuisance(
        ambient_db_a=level,
        mic_gain_db=day.uniform(-cal.GAIN_DRIFT_DB, cal.GAIN_DRIFT_DB, 2),
        mic_dc_counts=cal.DC_OFFSET_COUNTS + day.normal(0.0, cal.DC_DRIFT_COUNTS, 2),
        force_bias_n=float(day.normal(0.0, cal.FORCE_BIAS_N)),
        grasp_mm=float(trial.uniform(*cal.GRASP_RANGE_MM)),
        fold=float(1.0 + trial.uniform(-cal.FOLD_SPREAD, cal.FOLD_SPREAD)),
        speed=float(1.0 + trial.normal(0.0, cal.SPEED_JITTER)),
        frame_phase_s=float(trial.uniform(0.0, 1.0 / archive.STEP_RATE)),
        contact_offset_mm=trial.normal(0.0, cal.CONTACT_OFFSET_MM, 2),
        temperature_c=climate[0],
        humidity_pct=climate[1],
        friction_scale=rig.friction_scale(*climate) if climate[0] is not None else 1.0,
        silicone_scale=rig.silicone_scale(climate[0]) if climate[0] is not None else 1.0,
        fuzz_scale=rig.fuzz_scale(scene.history, scene.cycles) if scene.wants("wear") else 1.0,
    )
