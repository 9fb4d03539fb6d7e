"""Each sound at each microphone per octave band, and whether the microphones' band levels follow the
fabric, the recording day or the condition (`python -m experiments.palm_physics`).

The simulator measured by its own functions; no model, no accuracy:

* Sources. `sim.trial.sound_sources` gives each sound the scene calls for at both microphones, as
  pressure at the port (an ideal microphone: nominal gain, no self-noise): the thumb's contact (in
  Minsound through the shell; at the palm radiated by the fingertip), the middle finger's contact
  and the cloth (at the palm only), the servos, the lab room's floor and events and, in the cafe,
  the loudspeaker. One scene per class on the first lab day and on the first cafe day; the SPH0645's
  self-noise alone for comparison. Levels are over the rubbing part of each trial (from the first
  step of `meta.closing_steps` on), by Parseval: dB SPL per octave band (`BANDS_HZ`, bins up to the
  model's 15 kHz) and A-weighted over 50 Hz-15 kHz (the paper's sound meter reads dB(A)).
* Lab events are rare in a short scene, so they are measured on their own: each lab day's events
  over `EVENT_MINUTES` (`sim.ambient.events`), as an equivalent level at the hand.
* Fabric, day or condition. The complete signals (every effect, as `ensure_dataset` simulates them)
  of every training class on every lab and cafe day of the preset, `TRIALS` trials each: per trial
  and band, the level in dB of the recorded words; an analysis of variance splits the per-trial
  levels' variance into fabric, condition, day within condition, fabric x day and trial shares,
  over the lab days alone and over all days.
* Transfer. Each radiator's path from the contact to the palm (`sim.air_path.palm_transfers`) and
  the shell's transmission loss for outside sound, per band centre.

Scenes are short (`CYCLES` rubbing cycles, ~1.5 s of rubbing): a level is a mean over the rubbing
and does not need a 30 s trial.
"""

from __future__ import annotations

import time
from typing import Any, Mapping, Sequence

import numpy as np
from tqdm import tqdm

from fabricjax import catalog, presets
from fabricjax.reporting import results_files
from fabricjax.sim import EFFECTS, Scene, acoustics, air_path, ambient, shell, simulate, sph0645, trial
from fabricjax.sim import calibration as cal
from fabricjax.store import archive
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents

CYCLES = 3
TRIALS = 2
EVENT_MINUTES = 3.0
BANDWIDTH_KHZ = 15.0  # the model's PSD bandwidth [paper]
OCTAVE_CENTRES_HZ = (125, 250, 500, 1000, 2000, 4000, 8000)
# Octave bands (IEC 61260 base-2 edges f / sqrt 2 .. f * sqrt 2), and the 16 kHz octave cut at the
# model's 15 kHz bandwidth.
BANDS_HZ = tuple((c / np.sqrt(2), c * np.sqrt(2)) for c in OCTAVE_CENTRES_HZ) + (
    (16000 / np.sqrt(2), BANDWIDTH_KHZ * 1000),
)
BAND_NAMES = tuple(f"{c / 1000:g}k" if c >= 1000 else f"{c}" for c in OCTAVE_CENTRES_HZ) + ("16k (to 15k)",)
MICS = ("Minsound", "palm")
RUBBING = ("thumb contact", "middle contact", "cloth")  # what the palm hears of the fabric


def levels_db(x: np.ndarray) -> np.ndarray:
    """Octave-band levels (dB SPL, `BANDS_HZ`) and, last, the A-weighted level over 50 Hz-15 kHz of a
    pressure signal `x` (Pa), by Parseval."""
    x = np.asarray(x, np.float64) - np.mean(x)
    f = np.fft.rfftfreq(len(x), 1.0 / archive.AUDIO_RATE)
    power = np.abs(np.fft.rfft(x)) ** 2 * (2.0 / len(x) ** 2)  # mean square per bin (one-sided)
    bands = [power[(f >= lo) & (f < hi)].sum() for lo, hi in BANDS_HZ]
    a = (f >= cal.BAND_HZ[0]) & (f <= cal.BAND_HZ[1])
    weighted = (power[a] * acoustics.a_weighting(f[a]) ** 2).sum()
    return 10 * np.log10(np.maximum(np.array([*bands, weighted]), 1e-30) / acoustics.P_REF**2)


def rubbing_samples(window_end: np.ndarray, closing_steps: int) -> slice:
    """Audio samples of the rubbing part of a trial: the windows from the first rubbing step on."""
    return slice(int(window_end[closing_steps]) - archive.WINDOW, int(window_end[-1]))


def source_levels(scene: Scene) -> dict[str, dict[str, list[float]]]:
    """{source: {microphone: `levels_db`}} of every sound the scene calls for, over its rubbing."""
    proc = trial.procedure(scene)
    rub = rubbing_samples(proc.window_end, int(np.searchsorted(proc.frame_times, proc.motion.rubbing_start_s)))
    out: dict[str, dict[str, list[float]]] = {}
    for name, at_mics in trial.sound_sources(scene, proc.motion, proc.grid, proc.nuisance).items():
        out[name] = {
            MICS[m]: levels_db(proc.grid.irfft(spec)[rub]).tolist()
            for m, spec in enumerate(at_mics)
            if spec is not None
        }
    noise = sph0645.self_noise(proc.grid, scene.rng("sph0645_1", "trial"))
    out["SPH0645 self-noise"] = {"palm": levels_db(proc.grid.irfft(noise)[rub]).tolist()}
    return out


def recorded_levels(scene: Scene) -> np.ndarray:
    """(microphone, bands + 1) `levels_db` of the recorded words over the rubbing, at nominal sensitivity."""
    arch = simulate(scene)
    rub = rubbing_samples(arch.window_end[:, 0], arch.meta["closing_steps"])
    return np.stack([levels_db((arch.audio[m, rub] >> archive.SAMPLE_SHIFT) / cal.COUNTS_PER_PA) for m in range(2)])


def event_levels(day: int, seed: int, minutes: float = EVENT_MINUTES) -> list[float]:
    """`levels_db` at the hand of one lab day's events over `minutes` (equivalent level), zero-free."""
    scene = Scene(0, day=day, seed=seed)
    grid = acoustics.Grid.for_samples(int(minutes * 60 * archive.AUDIO_RATE))
    x = ambient.events(scene, grid, scene.rng("ambient", "trial"))
    return levels_db(np.zeros(grid.n) if x is None else x).tolist()


def variance_shares(x: np.ndarray, conditions: Sequence[str] | None = None) -> dict[str, np.ndarray]:
    """Balanced analysis of variance of x[fabric, day, trial, band]: each effect's share of the total sum of
    squares per band (fabric + day + fabric x day + trial = 1, the day split into condition and day within
    condition when `conditions` labels the days), and the day and fabric effects' SD in dB."""
    m = x.mean(axis=(0, 1, 2))
    mf, md, mfd = x.mean(axis=(1, 2)), x.mean(axis=(0, 2)), x.mean(axis=2)
    n_f, n_d, n_t = x.shape[:3]
    ss = {
        "fabric": n_d * n_t * ((mf - m) ** 2).sum(axis=0),
        "day": n_f * n_t * ((md - m) ** 2).sum(axis=0),
        "fabric x day": n_t * ((mfd - mf[:, None] - md[None] + m) ** 2).sum(axis=(0, 1)),
        "trial": ((x - mfd[:, :, None]) ** 2).sum(axis=(0, 1, 2)),
    }
    if conditions is not None:
        labels = np.asarray(conditions)
        mc = np.stack([md[labels == c].mean(axis=0) for c in labels])  # each day's condition mean
        ss["condition"] = n_f * n_t * ((mc - m) ** 2).sum(axis=0)
        ss["day within condition"] = n_f * n_t * ((md - mc) ** 2).sum(axis=0)
        del ss["day"]
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
    cafe_days = tuple(dataset.splits.cafe_days)
    days = (*lab_days, *cafe_days)
    conditions = ["lab"] * len(lab_days) + ["cafe"] * len(cafe_days)
    start = time.perf_counter()
    sources = {
        condition: {
            fid: source_levels(Scene(fid, day=day, condition=condition, cycles=cycles, seed=seed))
            for fid in tqdm(classes, desc=f"sources ({condition})", leave=False)
        }
        for condition, day_list in (("lab", lab_days), ("cafe", cafe_days))
        if day_list
        for day in day_list[:1]
    }
    events = {day: event_levels(day, seed) for day in lab_days}
    full = np.array(
        [
            [
                [
                    recorded_levels(
                        Scene(fid, day=day, trial=t, condition=c, effects=EFFECTS, cycles=cycles, seed=seed)
                    )
                    for t in range(trials)
                ]
                for day, c in zip(days, conditions)
            ]
            for fid in tqdm(classes, desc="complete signals", leave=False)
        ]
    )  # (fabric, day, trial, mic, band)
    lab = np.array([c == "lab" for c in conditions])
    f = np.array([np.sqrt(lo * hi) for lo, hi in BANDS_HZ])
    paths = air_path.palm_transfers(f, shell.contact_transfer(f))
    return {
        "preset": preset,
        "cycles": cycles,
        "trials": trials,
        "seed": seed,
        "classes": classes,
        "lab_days": list(lab_days),
        "cafe_days": list(cafe_days),
        "bands": list(BAND_NAMES) + ["dB(A)"],
        "sources": sources,
        "events": events,
        "event_minutes": EVENT_MINUTES,
        "full_levels": {mic: full[..., m, :].tolist() for m, mic in enumerate(MICS)},
        "shares_lab": {
            mic: {k: v.tolist() for k, v in variance_shares(full[:, lab][..., m, :]).items()}
            for m, mic in enumerate(MICS)
        },
        "shares_all": {
            mic: {k: v.tolist() for k, v in variance_shares(full[..., m, :], conditions).items()}
            for m, mic in enumerate(MICS)
        },
        "transfer": {
            "band_centre_hz": f.tolist(),
            **{f"{name} to palm [dB]": (20 * np.log10(np.abs(tf))).tolist() for name, tf in paths.items()},
            "shell transmission loss [dB]": shell.transmission_loss_db(f).tolist(),
        },
        "wall_s": time.perf_counter() - start,
    }


def _fmt(values: Sequence[float]) -> list[str]:
    return [f"{v:.1f}" for v in values]


def _power_sum(*levels: np.ndarray) -> np.ndarray:
    return 10 * np.log10(sum(10 ** (np.asarray(x) / 10) for x in levels))


def rubbing_at_palm(per_source: dict[str, dict[str, list[float]]]) -> np.ndarray:
    """Power sum of what the palm hears of the fabric (both contacts and the cloth), per band."""
    return _power_sum(*[per_source[k]["palm"] for k in RUBBING if k in per_source])


def room_at_palm(per_source: dict[str, dict[str, list[float]]]) -> np.ndarray:
    """Power sum of everything else the palm hears (room, servos, self-noise), per band."""
    return _power_sum(*[v["palm"] for k, v in per_source.items() if k not in RUBBING and "palm" in v])


def summary(doc: dict[str, Any]) -> list[str]:
    """What comes out, in a few lines computed from the tables below."""
    lines = []
    for condition, per_class in doc["sources"].items():
        rub = np.array([rubbing_at_palm(v) for v in per_class.values()])
        rest = np.array([room_at_palm(v) for v in per_class.values()])
        above = int(sum(np.any(r[:-1] > o[:-1]) for r, o in zip(rub, rest)))
        lines.append(
            f"- {condition}: the fabric at the palm (both contacts and the cloth) "
            f"{rub[:, -1].min():.0f}-{rub[:, -1].max():.0f} dB(A) "
            f"over the classes (median {np.median(rub[:, -1]):.0f}), everything else "
            f"{np.median(rest[:, -1]):.0f} dB(A); the fabric stands "
            f"above everything else in at least one octave band for {above} of {len(rub)} classes"
        )
    for mic in MICS:
        a, lab = doc["shares_all"][mic], doc["shares_lab"][mic]
        lines.append(
            f"- {mic}, share of the per-trial dB(A) variance: over all days fabric "
            f"{100 * a['fabric'][-1]:.1f} %, condition "
            f"{100 * a['condition'][-1]:.1f} %, day within condition "
            f"{100 * a['day within condition'][-1]:.1f} %, fabric x day "
            f"{100 * a['fabric x day'][-1]:.1f} %, trial {100 * a['trial'][-1]:.1f} %; over the lab days "
            f"fabric {100 * lab['fabric'][-1]:.1f} %, "
            f"day {100 * lab['day'][-1]:.1f} % (per octave band: day "
            f"{100 * min(lab['day'][:-1]):.1f}-{100 * max(lab['day'][:-1]):.1f} %)"
        )
    return lines


def markdown(doc: dict[str, Any]) -> str:
    """The page: each source at each microphone per condition, the lab's events, the fabric against
    the rest at the palm, the variance shares and the paths."""
    return "\n".join(
        [
            *_intro_markdown(doc),
            *(
                line
                for condition, per_class in doc["sources"].items()
                for line in _sources_markdown(doc, condition, per_class)
            ),
            *_events_markdown(doc),
            *_margin_markdown(doc),
            *_shares_markdown(doc),
            *_paths_markdown(doc),
        ]
    )


def _intro_markdown(doc: dict[str, Any]) -> list[str]:
    """The title, where the numbers come from and the scenes, and the summary."""
    return [
        "# Each sound at each microphone: the fabric against the room; fabric, day and condition",
        "",
        documents.header_markdown(doc).rstrip("\n"),
        f"- scenes: preset {doc['preset']}'s {len(doc['classes'])} training classes, lab days "
        f"{doc['lab_days']}, cafe days "
        f"{doc['cafe_days']}, {doc['trials']} trials per day, {doc['cycles']} rubbing cycles per trial "
        f"(levels over the rubbing), "
        f"seed {doc['seed']}; {doc['wall_s']:.0f} s",
        "",
        "How each number is made: `fabricjax/studies/diagnostics/palm.py`; where each simulator magnitude comes from: "
        '`fabricjax/sim/calibration.py` ("air paths", "ambient sound", "servo noise"). Levels in dB SPL at '
        "the microphone's "
        "port per octave band and A-weighted over 50 Hz-15 kHz.",
        "",
        *summary(doc),
        "",
    ]


def _sources_markdown(doc: dict[str, Any], condition: str, per_class: Mapping[str, Any]) -> list[str]:
    """Each source at each microphone in one condition: the least, median and largest over the
    classes' scenes of the fabric's own sounds, the median of the others."""
    bands = doc["bands"]
    names = list(next(iter(per_class.values())))
    for extra in per_class.values():
        names += [n for n in extra if n not in names]
    rows = []
    for name in names:
        for mic in MICS:
            per = np.array([v[name][mic] for v in per_class.values() if name in v and mic in v[name]])
            if len(per) == 0:
                continue
            stats = (("min", per.min(axis=0)), ("median", np.median(per, axis=0)), ("max", per.max(axis=0)))
            for label, values in stats if name in RUBBING else stats[1:2]:
                rows.append(
                    [
                        f"{name} at {mic}: {label}" + ("" if name in RUBBING else f" over {len(per)} classes' scenes"),
                        *_fmt(values),
                    ]
                )
    rub = np.array([rubbing_at_palm(v) for v in per_class.values()])
    rows.append(
        ["the fabric at the palm (power sum of the contacts and the cloth): median", *_fmt(np.median(rub, axis=0))]
    )
    rows.append(
        [
            "everything else at the palm: median",
            *_fmt(np.median([room_at_palm(v) for v in per_class.values()], axis=0)),
        ]
    )
    day = doc["lab_days"][0] if condition == "lab" else doc["cafe_days"][0]
    return [
        f"## Each source at each microphone: {condition}, day {day}",
        "",
        results_files.markdown_table(["source", *bands], rows),
    ]


def _events_markdown(doc: dict[str, Any]) -> list[str]:
    """The lab's events per day, and the heading of the margin table that follows."""
    bands = doc["bands"]
    return [
        f"## Lab events per day (equivalent level at the hand over {doc['event_minutes']:g} min)",
        "",
        "The day's activity (`sim.ambient.events`: voices, footsteps, doors at their sourced rates and "
        "levels) sets how "
        "much the lab's sound changes between days; -inf-like values: no event that day.",
        "",
        results_files.markdown_table(["lab day", *bands], [[d, *_fmt(v)] for d, v in doc["events"].items()]),
        "## Rubbing against everything else at the palm, per class (dB)",
        "",
        "The fabric at the palm minus the power sum of everything else it hears (room, servos, self-noise), per band. "
        "Positive: the fabric stands above the rest.",
        "",
    ]


def _margin_markdown(doc: dict[str, Any]) -> list[str]:
    """The fabric at the palm minus everything else it hears, per class and condition."""
    bands = doc["bands"]
    per_cond = doc["sources"]
    rows = []
    for fid in doc["classes"]:
        cells = []
        for condition in per_cond:
            v = per_cond[condition][fid]
            cells += _fmt(rubbing_at_palm(v) - room_at_palm(v))
        rows.append([f"{fid} {catalog.fabric(int(fid)).name}", *cells])
    return [results_files.markdown_table(["class", *[f"{c} {b}" for c in per_cond for b in bands]], rows)]


def _shares_markdown(doc: dict[str, Any]) -> list[str]:
    """The fabric's, the day's and the condition's shares of the per-trial level variance."""
    bands = doc["bands"]
    lines = [
        "## Fabric, day and condition: shares of the per-trial level variance (complete signals)",
        "",
        "Analysis of variance of each trial's band level (dB, recorded words at nominal sensitivity) over "
        "classes x days x "
        "trials; the shares add up to 1 per band. Lab days alone, then all days with the day split into the condition "
        "(lab or cafe) and the day within it. `day SD` / `fabric SD`: SD of the day / class means about the "
        "grand mean (dB).",
        "",
    ]
    for key, label in (("shares_lab", "lab days"), ("shares_all", "all days")):
        for mic in ("palm", "Minsound"):
            sh = doc[key][mic]
            rows = [[k, *[f"{v:.2f}" if "SD" in k else f"{100 * v:.1f} %" for v in sh[k]]] for k in sh]
            lines += [f"**{mic}, {label}**", "", results_files.markdown_table(["share", *bands], rows)]
    return lines


def _paths_markdown(doc: dict[str, Any]) -> list[str]:
    """The palm's transfer per radiator and the shell's transmission loss, per band."""
    t = doc["transfer"]
    cols = [k for k in t if k != "band_centre_hz"]
    return [
        "## The paths",
        "",
        "Palm pressure per contact pressure (the contact's equivalent Minsound cavity pressure) for each radiator "
        "(`sim.air_path.palm_transfers`), and the shell's transmission loss for outside sound, at each "
        "band's centre (dB).",
        "",
        results_files.markdown_table(
            ["band centre [Hz]", *cols],
            [[f"{fc:.0f}", *[f"{t[c][i]:.1f}" for c in cols]] for i, fc in enumerate(t["band_centre_hz"])],
        ),
    ]


def run(preset: str = "default", cycles: int = CYCLES, where: Location = Location()) -> dict[str, Any]:
    """Measure, then write results/palm_physics.md and .json atomically."""
    doc = {**documents.header("palm_physics", module=__name__, command=where.command), **measure(preset, cycles)}
    return results_files.write(where.results_dir(), doc, markdown)
