"""`simulate(scene)`: one trial archive, computing only the effects and streams the scene calls for.

Order of work: the finger motion (always: it is the procedure and fixes the time base), then each
listed sound effect adds its spectrum to the contact, servo and ambient sources, which are mixed
into the two microphones through their paths; proprioception and force are sampled at the frame
times; images are rendered only when "images" is among the streams. Each effect draws from its own
generator (`Scene.rng`), so switching one effect off leaves the others' draws unchanged.
"""

from __future__ import annotations

import numpy as np

from fabricjax import archive
from fabricjax.sim import acoustics, air_path, ambient, minsight, motion, proprio, servo, shell, sph0645, stick_slip, texture
from fabricjax.sim import calibration as cal
from fabricjax.sim.scene import Scene, nuisance


def frame_times(duration_s: float, phase_s: float, rng: np.random.Generator) -> np.ndarray:
    """Camera frame capture times: 50 Hz from `phase_s` with small jitter, non-decreasing."""
    n = int(np.floor((duration_s - phase_s) * archive.STEP_RATE)) + 1
    t = phase_s + np.arange(n) / archive.STEP_RATE + rng.uniform(-cal.FRAME_JITTER_S, cal.FRAME_JITTER_S, n)
    return np.maximum.accumulate(np.clip(t, 0.0, duration_s))


def microphones(scene: Scene, mot: motion.Motion, grid: acoustics.Grid, nz) -> np.ndarray:
    """int32 (2, n) I2S words: row 0 Minsound (inside the shell), row 1 the palm microphone."""
    f = grid.f
    inside = np.zeros(len(f), np.complex128)
    palm = np.zeros(len(f), np.complex128)
    contact = np.zeros(len(f), np.complex128)
    if scene.wants("texture") or scene.wants("stick_slip"):
        t = grid.t
        slide = np.interp(t, mot.t, mot.slide_mm)
        normal = np.interp(t, mot.t, mot.normal_n, left=0.0, right=0.0)
        if scene.wants("texture"):
            contact += grid.rfft(texture.vibration(
                scene, slide, normal, nz.grasp_mm, scene.rng("texture", "trial"), nz.fuzz_scale
            ))
        if scene.wants("stick_slip"):
            contact += stick_slip.spectrum(scene, mot, grid, scene.rng("stick_slip", "trial"))
    inside += contact * shell.contact_transfer(f) if scene.wants("shell") else contact
    if scene.wants("air_path"):
        palm += contact * air_path.contact_transfer(f)
    if scene.wants("servo_noise"):
        src = servo.source(mot, grid, scene.rng("servo_noise", "trial"))
        inside += src * servo.internal_transfer(f)
        palm += src * servo.palm_transfer(f)
    if scene.wants("ambient"):
        amb = ambient.spectrum(scene.condition, nz.ambient_db_a, grid, scene.rng("ambient", "trial"))
        inside += amb * shell.airborne_transfer(f) if scene.wants("shell") else amb
        palm += amb
    rngs = [scene.rng(f"sph0645_{m}", "trial") if scene.wants("sph0645") else None for m in range(2)]
    return np.stack([sph0645.record(spec, grid, m, nz, rngs[m]) for m, spec in enumerate((inside, palm))])


def simulate(scene: Scene) -> archive.TrialArchive:
    """The trial archive of `scene` (validated; `images` is None unless "images" is streamed)."""
    fab = scene.fabric
    nz = nuisance(scene)
    mot = motion.finger_motion(fab, scene.cycles, nz, scene.rng("motion", "trial"))
    t = frame_times(mot.duration_s, nz.frame_phase_s, scene.rng("frames", "trial"))
    window_end = cal.LEAD_IN + np.round(t * archive.AUDIO_RATE).astype(np.int64)
    grid = acoustics.Grid.for_samples(int(window_end[-1]))
    audio = microphones(scene, mot, grid, nz)
    joints, force = proprio.joints_and_force(mot, t, nz, scene.rng("proprioception", "trial") if scene.wants("proprioception") else None)
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
        )
    )
