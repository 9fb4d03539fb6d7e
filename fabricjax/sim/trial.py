"""`simulate(scene)`: one trial archive, computing only the effects and streams the scene calls for.

Order of work: the finger motion (always: it is the procedure and fixes the time base), then each
listed sound effect computes its sources (both fingertips' contacts, the cloth, the servos, the
room) at the two microphones through their paths (`sound_sources`), which are summed and recorded; proprioception and
force are sampled at the frame
times; images are rendered only when "images" is among the streams. Each effect draws from its own
generator (`Scene.rng`), so switching one effect off leaves the others' draws unchanged.
"""

from __future__ import annotations

import dataclasses
import importlib

import numpy as np

from fabricjax.sim import (
    acoustics,
    air_path,
    ambient,
    estimates,
    minsight,
    motion,
    proprio,
    servo,
    shell,
    sph0645,
    stick_slip,
    texture,
)
from fabricjax.sim import calibration as cal
from fabricjax.sim.scene import Nuisance, Scene, nuisance
from fabricjax.store import archive


def frame_times(duration_s: float, phase_s: float, rng: np.random.Generator) -> np.ndarray:
    """Camera frame capture times: 50 Hz from `phase_s` with small jitter, non-decreasing."""
    n = int(np.floor((duration_s - phase_s) * archive.STEP_RATE)) + 1
    t = phase_s + np.arange(n) / archive.STEP_RATE + rng.uniform(-cal.FRAME_JITTER_S, cal.FRAME_JITTER_S, n)
    return np.maximum.accumulate(np.clip(t, 0.0, duration_s))


def middle_grasp_mm(grasp_mm: float, rng: np.random.Generator) -> float:
    """Where on the strip the middle finger rubs: the fold's other face, twice the pinch's distance from the
    fold line further along the strip (wrapped into the grasp range)."""
    lo, hi = cal.GRASP_RANGE_MM
    return float(lo + (grasp_mm + 2 * rng.uniform(*cal.FOLD_LINE_MM) - lo) % (hi - lo))


def contact(
    scene: Scene,
    mot: motion.Motion,
    grid: acoustics.Grid,
    slide_normal,
    grasp_mm: float,
    names: tuple[str, str],
    fuzz_scale: float,
) -> np.ndarray:
    """Spectrum (cavity-equivalent Pa) of one fingertip's contact: texture (read along `slide_normal`, the
    slide position and normal force per audio sample, on the strip as worn by `fuzz_scale`) and stick-slip,
    as the scene calls for."""
    spec = np.zeros(len(grid.f), np.complex128)
    if scene.wants("texture"):
        spec += grid.rfft(texture.vibration(scene, *slide_normal, grasp_mm, scene.rng(names[0], "trial"), fuzz_scale))
    if scene.wants("stick_slip"):
        spec += stick_slip.spectrum(scene, mot, grid, scene.rng(names[1], "trial"))
    return spec


def sound_sources(
    scene: Scene, mot: motion.Motion, grid: acoustics.Grid, nz
) -> dict[str, tuple[np.ndarray | None, np.ndarray | None]]:
    """Pressure spectra (Pa) of each sound the scene calls for at (Minsound's microphone, the palm microphone);
    None where a sound does not reach that microphone (calibration, "air paths", bounds what is left out)."""
    f = grid.f
    out = {}
    rubbing = scene.wants("texture") or scene.wants("stick_slip")
    if rubbing:
        t = grid.t
        slide = np.interp(t, mot.t, mot.slide_mm)
        normal = np.interp(t, mot.t, mot.normal_n, left=0.0, right=0.0)
        thumb = contact(scene, mot, grid, (slide, normal), nz.grasp_mm, ("texture", "stick_slip"), nz.fuzz_scale)
        wall = shell.contact_transfer(f) if scene.wants("shell") else 1.0
        paths = air_path.palm_transfers(f, wall) if scene.wants("air_path") else None
        out["thumb contact"] = (thumb * wall, None if paths is None else thumb * paths["thumb"])
        if paths is not None and scene.fabric.is_fabric:
            grasp = middle_grasp_mm(nz.grasp_mm, scene.rng("middle_patch", "trial"))
            middle = contact(
                scene, mot, grid, (-slide, normal), grasp, ("texture_middle", "stick_slip_middle"), nz.fuzz_scale
            )  # opposite phase
            out["middle contact"] = (None, middle * paths["middle"])
            out["cloth"] = (None, (thumb - middle) * paths["cloth"])
        elif paths is not None:  # no cloth: the two shells rub each other, one contact indents both
            out["middle contact"] = (None, thumb * paths["middle"])
    if scene.wants("servo_noise"):
        src = servo.source(mot, grid, scene.rng("servo_noise", "trial"))
        out["servos"] = (src * servo.internal_transfer(f), src * servo.palm_transfer(f))
    if scene.wants("ambient"):
        loss = shell.airborne_transfer(f) if scene.wants("shell") else 1.0
        for name, (palm, outside) in ambient.spectra(
            scene, nz.ambient_db_a, grid, scene.rng("ambient", "trial")
        ).items():
            out[name] = (outside * loss, palm)
    return out


def microphones(scene: Scene, mot: motion.Motion, grid: acoustics.Grid, nz) -> np.ndarray:
    """int32 (2, n) I2S words: row 0 Minsound (inside the shell), row 1 the palm microphone."""
    total = [np.zeros(len(grid.f), np.complex128), np.zeros(len(grid.f), np.complex128)]
    for at_mics in sound_sources(scene, mot, grid, nz).values():
        for m, spec in enumerate(at_mics):
            if spec is not None:
                total[m] += spec
    rngs = [scene.rng(f"sph0645_{m}", "trial") if scene.wants("sph0645") else None for m in range(2)]
    return np.stack([sph0645.record(spec, grid, m, nz, rngs[m]) for m, spec in enumerate(total)])


@dataclasses.dataclass(frozen=True)
class Procedure:
    """What fixes a trial's time base: the day's and trial's nuisance, the finger motion, the frame times."""

    nuisance: Nuisance
    motion: motion.Motion
    frame_times: np.ndarray
    window_end: np.ndarray  # audio sample (lead-in included) at which each step's window ends
    grid: acoustics.Grid


def procedure(scene: Scene) -> Procedure:
    nz = nuisance(scene)
    mot = motion.finger_motion(scene.fabric, scene.cycles, nz, scene.rng("motion", "trial"))
    t = frame_times(mot.duration_s, nz.frame_phase_s, scene.rng("frames", "trial"))
    window_end = cal.LEAD_IN + np.round(t * archive.AUDIO_RATE).astype(np.int64)
    return Procedure(nz, mot, t, window_end, acoustics.Grid.for_samples(int(window_end[-1])))


_MODULES = (acoustics, air_path, ambient, minsight, motion, proprio, servo, shell, sph0645, stick_slip, texture)
_applied: tuple[tuple[str, float], ...] = ()  # the estimates `calibration` holds now (`Scene.estimates`)


def use_estimates(values: tuple[tuple[str, float], ...]) -> None:
    """Set `calibration`'s estimates to the registry's values overridden by `values` (its
    constants, derived ones included, are computed again), and drop every cached result computed
    from the previous ones; only when they change: a process simulates many scenes of one point."""
    global _applied
    if values == _applied:
        return
    estimates.override(dict(values))
    importlib.reload(cal)
    for module in _MODULES:
        for v in vars(module).values():
            if hasattr(v, "cache_clear"):
                v.cache_clear()
    _applied = values


def simulate(scene: Scene) -> archive.TrialArchive:
    """The trial archive of `scene` (validated; `images` is None unless "images" is streamed),
    with the scene's estimates (`Scene.estimates`) in force."""
    use_estimates(scene.estimates)
    fab = scene.fabric
    proc = procedure(scene)
    nz, mot, t, window_end = proc.nuisance, proc.motion, proc.frame_times, proc.window_end
    audio = microphones(scene, mot, proc.grid, nz)
    joints, force = proprio.joints_and_force(
        mot, t, nz, scene.rng("proprioception", "trial") if scene.wants("proprioception") else None
    )
    images = minsight.render(scene, mot, t, nz, scene.rng("minsight", "trial")) if "images" in scene.streams else None
    meta = archive.make_meta(
        fabric_id=fab.id,
        properties=fab.properties,
        day=scene.day,
        trial=scene.trial,
        condition=scene.condition,
        source={"kind": "simulated", "scene": scene.to_json(), "effects": list(scene.effects)},
        image_size=scene.image_size if images is not None else None,
        closing_steps=int(np.searchsorted(t, mot.rubbing_start_s)),  # as the recorder writes it
        **({"reference": reference_meta(scene)} if images is not None else {}),
    )
    return archive.validate(
        archive.TrialArchive(
            meta=meta,
            timestamps=t.astype(np.float64),
            window_end=np.stack([window_end, window_end], axis=1),
            joints=joints,
            force=force,
            audio=audio,
            images=images,
            reference=None if images is None else minsight.reference(scene),
        )
    )


def reference_meta(scene: Scene) -> dict:
    """`meta.reference` of a simulated trial: its session (day and condition) took
    `archive.REFERENCE_FRAMES` no-contact frames at its start, after the camera's warm-up, as the
    recorder does (`minsight.reference`)."""
    return {
        "how": f"simulated: {archive.REFERENCE_FRAMES} no-contact frames after the camera's warm-up, at the "
        "session's start",
        "session": f"day{scene.day}_{scene.condition}",
        "times_s": None,
    }
