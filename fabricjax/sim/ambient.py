"""The room's sound at the two microphones: the lab's floor and events, and the cafe's loudspeaker.

[paper, Robustness] Lab noise near the palm microphone measured 29-31 dB(A); the cafe test set was
recorded "while playing audible noise" resembling a coffee shop, 47-55 dB(A). Magnitudes and
sources: calibration, "ambient sound".
* lab floor: ventilation and building noise of the shape of a noise-criterion curve, scaled to the
  level `scene.nuisance` draws per day and trial; a diffuse field, so its coherence between the palm
  microphone and Minsound's shell is sin(k d) / (k d) for their distance d;
* lab events: voices, footsteps and doors at Poisson times, as busy as the day (`scene.rng(...,
  "day")`) makes the lab, each at its sourced level and distance, reaching both microphones through
  the room's response;
* cafe: a coffee-shop recording (babble with the long-term speech spectrum, a residual syllabic
  modulation and clatter) played from a loudspeaker placed per day: its direct sound reaches each
  microphone along its own path and delay, its reverberant sound through the room's response at
  each microphone. The level at the palm is the drawn one; Minsound's follows from the geometry.
  The lab's floor and events go on underneath.
The room's response at the two microphones (drawn per day) is the Schroeder picture of a reverberant
room: decaying noise of the room's reverberation time, whose two points' responses have the diffuse
field's coherence.
"""

from __future__ import annotations

import functools

import numpy as np

from fabricjax.sim import acoustics, air_path
from fabricjax.sim import calibration as cal
from fabricjax.sim.scene import Scene
from fabricjax.store import archive

ROOM_RESPONSE_LEN = (
    2**16
)  # [numerics] samples of the drawn room responses (1.37 s: the 0.6 s T60 decay reaches -137 dB)


def octave_shape(f: np.ndarray, octave_db: dict[float, float]) -> np.ndarray:
    """Amplitude spectrum (any scale) whose octave-band levels follow `octave_db` (interpolated in log f)."""
    fc = np.array(list(octave_db), float)
    density_db = np.array(list(octave_db.values())) - 10 * np.log10(fc / np.sqrt(2))  # per Hz of an octave's width
    log_f = np.log(np.maximum(np.asarray(f, np.float32), np.float32(20.0)))  # [numerics] flat below 20 Hz (log 0)
    return np.exp(np.interp(log_f, np.log(fc), density_db * (np.log(10) / 20)).astype(np.float32))


def diffuse_coherence(f: np.ndarray) -> np.ndarray:
    """sin(k d) / (k d) between the palm microphone and Minsound's shell (Cook et al. 1955)."""
    d = air_path.distance_m(cal.PALM_MIC_M, cal.THUMB_TIP_M)
    return np.sinc(np.asarray(f, np.float32) * np.float32(2 * d / cal.SOUND_SPEED_M_S))


def room_constant_m2() -> float:
    """Sabine absorption 0.161 V / T60, taken as the room constant R."""
    return cal.SABINE_S_PER_M * cal.ROOM_VOLUME_M3 / cal.ROOM_T60_S


@functools.lru_cache(maxsize=16)  # [numerics]
def room_responses(seed: int, day: int, condition: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frequencies, palm, Minsound) unit-power reverberant responses of the day's room (cached: pure)."""
    rng = Scene(0, day=day, condition=condition, seed=seed).rng("room", "day")
    t = np.arange(ROOM_RESPONSE_LEN) / archive.AUDIO_RATE
    decay = np.exp(-3 * np.log(10) * t / cal.ROOM_T60_S)  # -60 dB after T60
    h = rng.standard_normal((2, ROOM_RESPONSE_LEN)) * decay
    h /= np.sqrt((h**2).sum(axis=1, keepdims=True))
    f = np.fft.rfftfreq(ROOM_RESPONSE_LEN, 1.0 / archive.AUDIO_RATE)
    palm, other = np.fft.rfft(h, axis=1)
    gamma = diffuse_coherence(f)
    return f, palm, gamma * palm + np.sqrt(1 - gamma**2) * other


def on_grid(f: np.ndarray, fr: np.ndarray, response: np.ndarray) -> np.ndarray:
    return np.interp(f, fr, response.real) + 1j * np.interp(f, fr, response.imag)


def floor(grid: acoustics.Grid, level_db_a: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The lab floor at (palm, Minsound's shell): diffuse noise of the NC curve's shape at `level_db_a` at the palm."""
    shape = octave_shape(grid.f, cal.LAB_FLOOR_OCTAVE_DB)
    palm = acoustics.noise_spectrum(rng, grid, shape)
    other = acoustics.noise_spectrum(rng, grid, shape)
    gamma = diffuse_coherence(grid.f)
    gain = acoustics.gain_to_db_a(palm, grid, level_db_a)
    return palm * gain, (gamma * palm + np.sqrt(1 - gamma**2) * other) * gain


def event_level_db_a(level_1m_db_a: float, distance_m: float) -> float:
    """Level at the hand of a source of `level_1m_db_a` in free field at 1 m, `distance_m` away in the room
    (Hopkins-Stryker: direct Q / 4 pi r^2 plus reverberant 4 / R, Q = 1)."""
    return level_1m_db_a + 10 * np.log10(1 / distance_m**2 + 4 * np.pi * 4 / room_constant_m2())


def _burst(kind: str, seconds: float, rng: np.random.Generator) -> np.ndarray:
    """One event's waveform (unit A-weighted RMS before its envelope)."""
    g = acoustics.Grid.for_samples(max(int(seconds * archive.AUDIO_RATE), 64))  # [numerics] at least 64 samples
    t = np.arange(g.n) / archive.AUDIO_RATE
    if kind == "voice":
        shape = octave_shape(g.f, cal.SPEECH_OCTAVE_DB)
        env = 0.5 * (1 - np.cos(2 * np.pi * cal.SYLLABLE_HZ * t + rng.uniform(0, 2 * np.pi)))
    elif kind == "steps":
        shape = np.abs(acoustics.lowpass2(g.f, cal.STEP_LOWPASS_HZ)).astype(np.float32)
        since = (t + rng.uniform(0, 1 / cal.STEP_HZ)) % (1 / cal.STEP_HZ)
        env = np.exp(-since / cal.STEP_DECAY_S)
    else:  # door
        shape = octave_shape(g.f, cal.LAB_FLOOR_OCTAVE_DB)
        env = np.exp(-t / (seconds * cal.DOOR_DECAY_SHARE))
    x = g.irfft(acoustics.scale_to_db_a(acoustics.noise_spectrum(rng, g, shape), g, 20 * np.log10(1 / acoustics.P_REF)))
    return x * env


def events(scene: Scene, grid: acoustics.Grid, rng: np.random.Generator) -> np.ndarray | None:
    """Waveform (Pa, as the level at the hand) of the lab's events during the trial, None when there are none."""
    activity = scene.rng("lab_activity", "day").lognormal(0.0, cal.LAB_ACTIVITY_SIGMA)
    minutes = grid.n / archive.AUDIO_RATE / 60
    out = None
    for kind, (per_minute, level_1m, seconds) in cal.LAB_EVENTS.items():
        for _ in range(rng.poisson(per_minute * activity * minutes)):
            x = _burst(kind, rng.uniform(*seconds), rng)
            x *= acoustics.db_to_pa(event_level_db_a(level_1m, rng.uniform(*cal.EVENT_DISTANCE_M)))
            start = int(rng.integers(-len(x) + 1, grid.n))
            lo, hi = max(start, 0), min(start + len(x), grid.n)
            out = np.zeros(grid.n) if out is None else out
            out[lo:hi] += x[lo - start : hi - start]
    return out


def babble_shape(f: np.ndarray) -> np.ndarray:
    """Long-term average speech spectrum (many talkers)."""
    return octave_shape(f, cal.SPEECH_OCTAVE_DB)


def clatter(n: int, rng: np.random.Generator) -> np.ndarray:
    """Sparse impacts (relative to a unit-RMS babble), each three inharmonic partials at 2-7 kHz."""
    out = np.zeros(n)
    tau = cal.CLATTER_DECAY_S
    t = np.arange(int(5 * tau * archive.AUDIO_RATE)) / archive.AUDIO_RATE  # [numerics] each clink lasts 5 decay times
    spread = cal.CLATTER_DECAY_SPREAD
    for start in rng.integers(0, n, rng.poisson(cal.CLATTER_PER_S * n / archive.AUDIO_RATE)):
        partials = rng.uniform(*cal.CLATTER_RING_HZ, cal.CLATTER_PARTIALS)
        hit = sum(np.sin(2 * np.pi * fp * t + rng.uniform(0, 2 * np.pi)) for fp in partials) / cal.CLATTER_PARTIALS
        hit *= np.exp(-t / (tau * rng.uniform(1 - spread, 1 + spread))) * rng.lognormal(0.0, cal.CLATTER_LEVEL_SPREAD)
        stop = min(n, start + len(t))
        out[start:stop] += hit[: stop - start]
    return out


def recording(grid: acoustics.Grid, rng: np.random.Generator) -> np.ndarray:
    """Spectrum (any scale) of the coffee-shop recording the loudspeaker plays."""
    babble = grid.irfft(acoustics.noise_spectrum(rng, grid, babble_shape(grid.f)))
    babble /= babble.std()
    n_env = (
        int(grid.n / archive.AUDIO_RATE * (2 * cal.SYLLABLE_HZ)) + 2
    )  # syllable-rate envelope: two knots per syllable
    env = np.interp(np.linspace(0, n_env - 1, grid.n), np.arange(n_env), rng.standard_normal(n_env))
    x = babble * (1.0 + cal.BABBLE_MODULATION * env)
    x += clatter(grid.n, rng) * 10 ** (cal.CLATTER_PEAK_DB / 20)
    return grid.rfft(x)


def speaker_position_m(scene: Scene) -> np.ndarray:
    """Where the loudspeaker stands on this cafe day (hand frame, m)."""
    rng = scene.rng("speaker", "day")
    r, phi = rng.uniform(*cal.SPEAKER_DISTANCE_M), rng.uniform(0, 2 * np.pi)
    return np.array([r * np.cos(phi), 0.0, r * np.sin(phi)])


def loudspeaker(scene: Scene, grid: acoustics.Grid, level_db_a: float, room: tuple, rng: np.random.Generator):
    """The played recording at (palm, Minsound's shell): direct paths with their delays plus the room's response,
    scaled to `level_db_a` at the palm (Hopkins-Stryker: direct Q / 4 pi r^2 against reverberant 4 / R)."""
    s = recording(grid, rng)
    pos = speaker_position_m(scene)
    reverb = np.sqrt(4 / room_constant_m2())
    out = []
    for mic, resp in ((cal.PALM_MIC_M, room[0]), (cal.THUMB_TIP_M, room[1])):
        r = air_path.distance_m(pos, mic)
        out.append(s * (np.sqrt(cal.SPEAKER_Q / (4 * np.pi)) / r * air_path.delay(grid.f, r) + reverb * resp))
    scale = acoustics.gain_to_db_a(out[0], grid, level_db_a)
    return out[0] * scale, out[1] * scale


def spectra(
    scene: Scene, level_db_a: float, grid: acoustics.Grid, rng: np.random.Generator
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Spectra (Pa) of each room sound at (the palm microphone, the outside of Minsound's shell).

    `level_db_a` is the drawn level at the palm: the floor's in the lab, the loudspeaker's in the cafe
    (whose lab floor is drawn within `LAB_DB_A` for the day)."""
    lab_level = level_db_a if scene.condition == "lab" else scene.rng("cafe_floor", "day").uniform(*cal.LAB_DB_A)
    out = {"room floor": floor(grid, lab_level, rng)}
    f_room, palm_room, thumb_room = room_responses(scene.seed, scene.day, scene.condition)
    room = None
    x = events(scene, grid, rng)
    if x is not None:
        room = (on_grid(grid.f, f_room, palm_room), on_grid(grid.f, f_room, thumb_room))
        e = grid.rfft(x)
        out["room events"] = (e * room[0], e * room[1])
    if scene.condition == "cafe":
        room = room or (on_grid(grid.f, f_room, palm_room), on_grid(grid.f, f_room, thumb_room))
        out["cafe loudspeaker"] = loudspeaker(scene, grid, level_db_a, room, rng)
    return out
