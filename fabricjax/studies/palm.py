"""How loud the rubbing is at the palm microphone against the room, and whether the palm's
band levels follow the recording day or the fabric (`python -m experiments.palm_physics`).

The simulator measured by its own functions; no model, no accuracy:

* Sources alone. Each sound at the palm port is simulated by itself by leaving the other effects
  out (`Scene.effects`; leaving an effect out never changes another effect's draws), with an
  ideal microphone (no "sph0645": nominal gain, no self-noise), so a level is that source's sound
  pressure: the rubbing (texture + stick-slip through the air path), the servos, the room (lab or
  cafe, at the level the day and trial draw) and, simulated alone, the SPH0645's self-noise. The
  rubbing inside Minsound (through the shell) is given for comparison. The 18-bit word quantises
  an ideal microphone's pressure with a step of 1 / `COUNTS_PER_PA` Pa: levels within a few dB of
  `quantisation_floor_db` are that floor, not the source.
* Levels are over the rubbing part of each trial (the steps from `meta.closing_steps` on), from the
  PSDs the model reads (`welch.welch_psd`, bins up to 15 kHz): dB SPL per octave band (`BANDS_HZ`)
  and A-weighted over 50 Hz-15 kHz (the paper's sound meter reads dB(A)).
* Day or fabric. The complete palm and Minsound signals (every effect, as `ensure_dataset`
  simulates them) of every training class on every lab day of the preset, `TRIALS` trials each:
  per trial and band, the level in dB; a balanced two-way analysis of variance splits the
  per-trial levels' variance into fabric, day, fabric x day and trial-to-trial shares.
* Transfer. The simulator's lumped air path (`air_path.contact_transfer`) beside the fingertip's
  own radiation (`air_path.fingertip_radiation` after the shell), per band centre.

Scenes are short (`CYCLES` rubbing cycles, ~1.5 s of rubbing, ~75 steps): a level is a mean over
steps and does not need a 30 s trial.
"""

from __future__ import annotations

import time
from typing import Any, Sequence

import numpy as np

from fabricjax import archive, catalog, presets
from fabricjax.features import welch
from fabricjax.sim import EFFECTS, Scene, acoustics, air_path, shell, simulate
from fabricjax.sim import calibration as cal
from fabricjax.sim.scene import nuisance
from fabricjax.studies import documents

CYCLES = 3
TRIALS = 2
BANDWIDTH_KHZ = 15.0  # the model's PSD bandwidth [paper]
OCTAVE_CENTRES_HZ = (125, 250, 500, 1000, 2000, 4000, 8000)
# Octave bands (IEC 61260 base-2 edges f / sqrt 2 .. f * sqrt 2), and the 16 kHz octave cut at the
# model's 15 kHz bandwidth.
BANDS_HZ = tuple((c / np.sqrt(2), c * np.sqrt(2)) for c in OCTAVE_CENTRES_HZ) + ((16000 / np.sqrt(2), BANDWIDTH_KHZ * 1000),)
BAND_NAMES = tuple(f"{c / 1000:g}k" if c >= 1000 else f"{c}" for c in OCTAVE_CENTRES_HZ) + ("16k (to 15k)",)
SOURCES = {  # source -> (effects, microphone row)
    "rubbing at the palm": (("texture", "stick_slip", "air_path"), 1),
    "rubbing in Minsound": (("texture", "stick_slip", "shell"), 0),
    "servos at the palm": (("servo_noise",), 1),
}
PA2_PER_FS2 = (archive.FULL_SCALE / cal.COUNTS_PER_PA) ** 2  # full scale^2 -> Pa^2 at nominal sensitivity
BATCH = 32  # windows per welch_psd call: one compiled shape for every trial


def rubbing_psd(arch: archive.TrialArchive, mic: int) -> np.ndarray:
    """Mean PSD (Pa^2 / Hz at nominal sensitivity, bins up to 15 kHz) over the rubbing steps."""
    ends = arch.window_end[arch.meta["closing_steps"] :, mic]
    windows = np.stack([arch.audio[mic, e - archive.WINDOW : e] for e in ends])
    pad = -len(windows) % BATCH
    padded = np.concatenate([windows, np.zeros((pad, archive.WINDOW), windows.dtype)])
    psd = np.concatenate([np.asarray(welch.welch_psd(b, bandwidth_khz=BANDWIDTH_KHZ, log=False)) for b in np.split(padded, len(padded) // BATCH)])
    return psd[: len(windows)].astype(np.float64).mean(axis=0) * PA2_PER_FS2


def levels_db(psd: np.ndarray) -> np.ndarray:
    """Octave-band levels (dB SPL, `BANDS_HZ`) and, last, the A-weighted level over 50 Hz-15 kHz."""
    f = welch.frequencies(BANDWIDTH_KHZ)
    df = f[1] - f[0]
    bands = [psd[(f >= lo) & (f < hi)].sum() * df for lo, hi in BANDS_HZ]
    a = (f >= cal.BAND_HZ[0]) & (f <= cal.BAND_HZ[1])
    weighted = (psd[a] * acoustics.a_weighting(f[a]) ** 2).sum() * df
    return 10 * np.log10(np.maximum(np.array([*bands, weighted]), 1e-30) / acoustics.P_REF**2)


def quantisation_floor_db() -> np.ndarray:
    """`levels_db` of the 18-bit rounding alone (step 1 / COUNTS_PER_PA Pa, power step^2 / 12, white)."""
    f = welch.frequencies(BANDWIDTH_KHZ)
    density = (1.0 / cal.COUNTS_PER_PA) ** 2 / 12 / (archive.AUDIO_RATE / 2)
    return levels_db(np.full(len(f), density))


def trial_levels(scene: Scene, mic: int) -> np.ndarray:
    return scene_levels(scene, (mic,))[0]


def scene_levels(scene: Scene, mics: Sequence[int]) -> np.ndarray:
    """(len(mics), bands + 1) `levels_db` of one simulated scene's microphones."""
    arch = simulate(scene)
    return np.stack([levels_db(rubbing_psd(arch, mic)) for mic in mics])


def variance_shares(x: np.ndarray) -> dict[str, np.ndarray]:
    """Balanced two-way ANOVA of x[fabric, day, trial, band]: each effect's share of the total sum of
    squares per band (fabric + day + fabric x day + trial = 1), and the day effects' SD in dB."""
    m = x.mean(axis=(0, 1, 2))
    mf, md, mfd = x.mean(axis=(1, 2)), x.mean(axis=(0, 2)), x.mean(axis=2)
    n_f, n_d, n_t = x.shape[:3]
    ss = {
        "fabric": n_d * n_t * ((mf - m) ** 2).sum(axis=0),
        "day": n_f * n_t * ((md - m) ** 2).sum(axis=0),
        "fabric x day": n_t * ((mfd - mf[:, None] - md[None] + m) ** 2).sum(axis=(0, 1)),
        "trial": ((x - mfd[:, :, None]) ** 2).sum(axis=(0, 1, 2)),
    }
    total = ((x - m) ** 2).sum(axis=(0, 1, 2))
    shares = {k: v / total for k, v in ss.items()}
    shares["day SD [dB]"] = (md - m).std(axis=0, ddof=1)
    shares["fabric SD [dB]"] = (mf - m).std(axis=0, ddof=1)
    return shares


def measure(preset: str = "default", cycles: int = CYCLES, trials: int = TRIALS, seed: int = 0) -> dict[str, Any]:
    """Every number of results/palm_physics.md (see the module docstring)."""
    dataset = presets.get(preset).dataset
    classes = [f for f in dataset.fabrics if f < catalog.N_CLASSES]
    lab_days = (*dataset.splits.train_days, *dataset.splits.test_days)
    cafe_days = dataset.splits.cafe_days
    first = lab_days[0]
    start = time.perf_counter()
    sources = {
        name: {fid: trial_levels(Scene(fid, day=first, effects=effects, cycles=cycles, seed=seed), mic).tolist() for fid in classes}
        for name, (effects, mic) in SOURCES.items()
    }
    rooms = []
    for condition, days in (("lab", lab_days), ("cafe", cafe_days)):
        for day in days:
            for trial in range(trials):
                scene = Scene(0, day=day, trial=trial, condition=condition, effects=("ambient",), cycles=cycles, seed=seed)
                nz = nuisance(scene)
                rooms.append({
                    "condition": condition, "day": day, "trial": trial, "drawn_db_a": nz.ambient_db_a,
                    "palm_gain_db": float(nz.mic_gain_db[1]), "levels": trial_levels(scene, 1).tolist(),
                })
    self_noise = trial_levels(Scene(0, day=first, effects=("sph0645",), cycles=cycles, seed=seed), 1)
    full = np.array([
        [[scene_levels(Scene(fid, day=day, trial=t, effects=EFFECTS, cycles=cycles, seed=seed), (0, 1)) for t in range(trials)] for day in lab_days]
        for fid in classes
    ])  # (fabric, day, trial, mic, band)
    f = np.array([np.sqrt(lo * hi) for lo, hi in BANDS_HZ])
    return {
        "preset": preset, "cycles": cycles, "trials": trials, "seed": seed, "classes": classes,
        "lab_days": list(lab_days), "cafe_days": list(cafe_days), "bands": list(BAND_NAMES) + ["dB(A)"],
        "quantisation_floor": quantisation_floor_db().tolist(),
        "sources": sources, "rooms": rooms, "self_noise": self_noise.tolist(),
        "full_levels": {"Minsound": full[..., 0, :].tolist(), "palm": full[..., 1, :].tolist()},
        "shares": {mic: {k: v.tolist() for k, v in variance_shares(full[..., m, :]).items()} for m, mic in enumerate(("Minsound", "palm"))},
        "transfer": {
            "band_centre_hz": f.tolist(),
            "air_path_db": (20 * np.log10(np.abs(air_path.contact_transfer(f)))).tolist(),
            "fingertip_db": (20 * np.log10(np.abs(shell.contact_transfer(f) * air_path.fingertip_radiation(f)))).tolist(),
        },
        "wall_s": time.perf_counter() - start,
    }


def _fmt(values: Sequence[float]) -> list[str]:
    return [f"{v:.1f}" for v in values]


def _power_sum(*levels: np.ndarray) -> np.ndarray:
    return 10 * np.log10(sum(10 ** (np.asarray(x) / 10) for x in levels))


def summary(doc: dict[str, Any]) -> list[str]:
    """What comes out, in three lines computed from the tables below."""
    rub = np.array(list(doc["sources"]["rubbing at the palm"].values()))[:, -1]
    rooms = {c: [r["levels"][-1] for r in doc["rooms"] if r["condition"] == c] for c in ("lab", "cafe")}
    palm = doc["shares"]["palm"]
    lab_sd = (cal.LAB_DB_A[1] - cal.LAB_DB_A[0]) / np.sqrt(12)
    gain_sd = cal.GAIN_DRIFT_DB / np.sqrt(3)
    return [
        f"- rubbing at the palm: {rub.min():.0f}-{rub.max():.0f} dB(A) over the classes (median {np.median(rub):.0f}); "
        f"room: lab {min(rooms['lab']):.1f}-{max(rooms['lab']):.1f} dB(A), cafe {min(rooms['cafe']):.1f}-{max(rooms['cafe']):.1f} "
        f"dB(A); SPH0645 self-noise {doc['self_noise'][-1]:.1f} dB(A)",
        f"- between lab days the room is drawn with an SD of {lab_sd:.2f} dB (uniform over `LAB_DB_A`) and each microphone's "
        f"gain with {gain_sd:.2f} dB (uniform within +-`GAIN_DRIFT_DB`); these {len(doc['lab_days'])} days' means scatter by "
        f"{palm['day SD [dB]'][-1]:.2f} dB(A) at the palm, the classes' by {palm['fabric SD [dB]'][-1]:.2f} dB(A)",
        f"- share of the palm's per-trial dB(A) variance: fabric {100 * palm['fabric'][-1]:.1f} %, day {100 * palm['day'][-1]:.1f} %, "
        f"fabric x day {100 * palm['fabric x day'][-1]:.1f} %, trial {100 * palm['trial'][-1]:.1f} %; per octave band: fabric "
        f"{100 * min(palm['fabric'][:-1]):.0f}-{100 * max(palm['fabric'][:-1]):.0f} %, day "
        f"{100 * min(palm['day'][:-1]):.1f}-{100 * max(palm['day'][:-1]):.1f} %",
    ]


def markdown(doc: dict[str, Any]) -> str:
    bands = doc["bands"]
    floor = np.array(doc["quantisation_floor"])
    rooms = doc["rooms"]
    lab = np.array([r["levels"] for r in rooms if r["condition"] == "lab"])
    cafe = np.array([r["levels"] for r in rooms if r["condition"] == "cafe"])
    noise = np.array(doc["self_noise"])
    rub = doc["sources"]["rubbing at the palm"]
    lines = [
        "# The palm microphone by physics: rubbing against the room, day against fabric",
        "",
        documents.header_markdown(doc).rstrip("\n"),
        f"- scenes: preset {doc['preset']}'s {len(doc['classes'])} training classes, lab days {doc['lab_days']}, cafe days "
        f"{doc['cafe_days']}, {doc['trials']} trials per day, {doc['cycles']} rubbing cycles per trial (levels are means over "
        f"the rubbing steps), seed {doc['seed']}; {doc['wall_s']:.0f} s",
        "",
        "How each number is made: `fabricjax/studies/palm.py`; where each simulator magnitude comes from: "
        "`fabricjax/sim/calibration.py` (the palm's account is under \"air paths\"). Levels in dB SPL per octave band "
        "(ideal microphone, nominal sensitivity) and A-weighted over 50 Hz-15 kHz; bins up to 15 kHz, the model's PSDs. "
        "Levels within ~3 dB of the 18-bit quantisation floor (last row of the first table) are the floor, not the source.",
        "",
        *summary(doc),
        "",
        "## Each source alone at the palm (and the rubbing inside Minsound)",
        "",
    ]
    rows = []
    for name in SOURCES:
        per = np.array(list(doc["sources"][name].values()))
        rows.append([f"{name}: min over classes", *_fmt(per.min(axis=0))])
        rows.append([f"{name}: median", *_fmt(np.median(per, axis=0))])
        rows.append([f"{name}: max", *_fmt(per.max(axis=0))])
    for day in doc["lab_days"]:
        rows.append([f"lab room, day {day} (mean of trials)", *_fmt(np.mean([r["levels"] for r in rooms if r["condition"] == "lab" and r["day"] == day], axis=0))])
    for day in doc["cafe_days"]:
        rows.append([f"cafe room, day {day} (mean of trials)", *_fmt(np.mean([r["levels"] for r in rooms if r["condition"] == "cafe" and r["day"] == day], axis=0))])
    rows.append(["cafe room minus lab room (means over days and trials)", *_fmt(cafe.mean(axis=0) - lab.mean(axis=0))])
    rows.append(["SPH0645 self-noise (palm, day %d)" % doc["lab_days"][0], *_fmt(noise)])
    rows.append(["18-bit quantisation floor (ideal microphone)", *_fmt(floor)])
    lines += [documents.markdown_table(["source", *bands], rows)]
    lines += [
        "Room levels as drawn per day and trial (`scene.nuisance`: the level the ambient is scaled to, dB(A)) and the palm "
        "microphone's gain drift of that day (dB):",
        "",
        documents.markdown_table(
            ["condition", "day", "trial", "room dB(A) drawn", "room dB(A) measured (50 Hz-15 kHz)", "palm gain drift [dB]"],
            [[r["condition"], r["day"], r["trial"], f"{r['drawn_db_a']:.2f}", f"{r['levels'][-1]:.2f}", f"{r['palm_gain_db']:+.2f}"] for r in rooms],
        ),
        "## Rubbing against everything else at the palm, per class (dB)",
        "",
        "Rubbing level minus the power sum of the room, the servos and the self-noise, per band: lab (mean room over "
        "the lab days) and cafe; the servos as heard while rubbing that class. Positive: the rubbing stands above what "
        "else the palm hears.",
        "",
    ]
    margins = {}
    for fid, lv in rub.items():
        servo = np.array(doc["sources"]["servos at the palm"][fid])
        margins[fid] = [np.array(lv) - _power_sum(room.mean(axis=0), servo, noise) for room in (lab, cafe)]
    rows = [[f"{fid} {catalog.fabric(int(fid)).name}", *_fmt(m_lab), *_fmt(m_cafe)] for fid, (m_lab, m_cafe) in margins.items()]
    lines += [documents.markdown_table(["class", *[f"lab {b}" for b in bands], *[f"cafe {b}" for b in bands]], rows)]
    above = [sum(bool(np.any(m[c][:-1] > 0)) for m in margins.values()) for c in (0, 1)]
    lines += [
        f"Classes whose rubbing stands above the rest in at least one octave band: lab {above[0]} of {len(rub)}, "
        f"cafe {above[1]} of {len(rub)}.",
        "",
        "## Day or fabric: shares of the per-trial level variance (complete signals, lab days)",
        "",
        "Balanced two-way analysis of variance of each trial's band level (dB) over classes x lab days x trials; the shares "
        "add up to 1 per band. `day SD` / `fabric SD`: standard deviation of the day / class means about the grand mean (dB).",
        "",
    ]
    for mic in ("palm", "Minsound"):
        sh = doc["shares"][mic]
        rows = [[k, *[f"{v:.2f}" if "SD" in k else f"{100 * v:.1f} %" for v in sh[k]]] for k in sh]
        lines += [f"**{mic}**", "", documents.markdown_table(["share", *bands], rows)]
    t = doc["transfer"]
    lines += [
        "## The air path against the fingertip's own radiation",
        "",
        "Palm pressure per contact pressure (dB): the simulator's lumped path (`air_path.contact_transfer`: fingertip "
        "and cloth together) and the fingertip's own monopole radiation after the shell "
        "(`shell.contact_transfer` x `air_path.fingertip_radiation`), at each band's centre.",
        "",
        documents.markdown_table(
            ["band centre [Hz]", "lumped air path [dB]", "fingertip alone [dB]"],
            [[f"{fc:.0f}", f"{a:.1f}", f"{b:.1f}"] for fc, a, b in zip(t["band_centre_hz"], t["air_path_db"], t["fingertip_db"])],
        ),
    ]
    return "\n".join(lines)


def run(preset: str = "default", cycles: int = CYCLES, command: str | None = None, results=None) -> dict[str, Any]:
    """Measure, then write results/palm_physics.md and .json atomically."""
    doc = {**documents.header("palm_physics", command=command), **measure(preset, cycles)}
    return documents.write(results, doc, markdown)
