"""What moves Minsight's imaged wall over a stroke, effect by effect, and what optical flow sees of it.

    python -m experiments.flow_budget --results=results

The optical-flow input carries little of the fabric (results/probe.md). This study measures why,
without a model: how far each simulated effect of the stroke moves the imaged wall, how much
optical flow a camera frame pair shows of it, and how that compares with the flow the camera's
shot noise makes on its own.

The effects. Minsight's frames follow the contact's loads at each frame (`minsight.FrameLoads`,
computed from the trial's motion by `minsight.frame_loads`); each load is one effect of the stroke:

    indentation  the normal force's swing over the stroke (the fingertips' arcs, the closing's load)
    shear        the skin's drag: the elastic stick and Coulomb slip of the contact (`motion.play`),
                 the tangential load over the shell's shear stiffness, the share the inner face keeps
    travel       the contact rolling along the convex shells with the stroke (`minsight.travel_mm`)
    texture      a coarse weave's or knit's relief sliding across the patch (`minsight.texture_relief`)

None of these is an effect of `Scene.effects` (those switch sounds, the joints' noise, the room's
climate and the cloth's wear): the frames' contact is switched here, in `FrameLoads`. Each
condition renders the trial's frames (`minsight.physical_frames`, with the trial's own patch,
`minsight.trial_contact`) under: every load as simulated ("all"); one load as simulated and the
others held ("<effect> alone": the indentation at its mean over the rubbing frames, the shear,
travel and slide at 0); every load held ("still": the contact present, nothing moving). Each
condition's frames are quantised twice: noise-free (rounded to whole DN, as the camera delivers)
and with the camera's shot noise, the same draws for every condition (`minsight.quantise` with
the trial's own generator, as `minsight.render` writes the archive's frames).

The flow: dense Farneback flow between consecutive frames by `features.flow.farneback`, the
method the preset's config names (`Config.flow_method`), over the rubbing frames only (closing
excluded). Per trial and condition: the mean and 95th percentile of the flow's magnitude over
the pixels of the image circle and the frame pairs, and the mean magnitude of the vectors the
paper's filter keeps (the top `flow.TOP_FRACTION` of each frame by magnitude: `kept_px`). The
signal over noise of a condition is its `kept_px` with shot noise over the still contact's with
the same noise: 1 when the kept vectors are the camera's noise alone.

The wall's own motion: per frame, at the contact's centre, the change of each load in mm (the
inner wall's normal displacement for the indentation and the texture, its drag for the shear, the
patch centre's roll for the travel), and in pixels of the frame by the camera's scale there
(`pixel_scale`: the view's Jacobian, `minsight._view`).

Fabric against trial: per effect and statistic, the share of the per-trial values' variance that
the fabric explains (eta squared, between-fabric sum of squares over the total), beside the share
chance alone gives ((k - 1) / (n - 1) for k fabrics and n trials).

At `SIZE` (the default preset's 60x80, the paper's image input) every effect is measured on every
trial of `TRIALS`; at the paper's flow resolution (`PAPER_SIZE`, 308x410: the paper computes flow
on the original frames) only "all" and "still", on the first trial, over its first
`PAPER_FRAMES` rubbing frames (rendering at 308x410 costs many times as much).
"""

from __future__ import annotations

import copy
import dataclasses
import math
import time
from typing import Any, Mapping, Sequence

import numpy as np

from fabricjax import catalog, presets
from fabricjax.config import Config
from fabricjax.errors import UserError
from fabricjax.features import flow
from fabricjax.reporting import results_files
from fabricjax.sim import Scene, minsight, trial
from fabricjax.sim import calibration as cal
from fabricjax.sim import dataset as sim_dataset
from fabricjax.store import archive, splits
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents

STUDY = "flow_budget"
TITLE, PAPER = "What moves Minsight's imaged wall over a stroke, and what optical flow sees of it", "not in the paper"
EFFECTS = ("indentation", "shear", "travel", "texture")
CONDITIONS = ("all", *EFFECTS, "still")
NOISE = ("noise-free", "shot noise")
TRIALS = ((1, 0), (1, 1), (2, 0), (3, 0))  # (day, trial), lab: two of a training day, one of the other, the test day's
CYCLES = 3  # rubbing cycles per trial: every effect repeats each stroke
SIZE = (60, 80)  # the paper's image input, the default preset's frames and flow
PAPER_SIZE = archive.MINSIGHT_SIZE  # the original frames the paper computes its flow on
PAPER_FRAMES = 25  # rubbing frames measured at PAPER_SIZE: one stroke at ~2 Hz
STREAMS = ("audio", "proprio", "images")
# Minsight's published figures the simulated magnitudes are compared with, and where each is
# published (as calibration.py, "Minsight images", cites them)
INSIGHT = "[insight] Sun, Kuchenbecker & Martius, Nature Machine Intelligence 4 (2022)"
MINSIGHT = "[minsight] Andrussow, Sun, Kuchenbecker & Martius, Advanced Intelligent Systems 5(8) (2023)"
PUBLISHED = {
    "spatial_resolution_mm": (0.4, f"Insight's spatial resolution, ~0.4 mm: {INSIGHT}"),
    "minsight_force_error_n": (0.07, f"Minsight's mean absolute force error over its surface, 0.07 N: {MINSIGHT}"),
    "insight_force_accuracy_n": (
        cal.FORCE_ACCURACY_N,
        f"Insight's force magnitude accuracy, ~{cal.FORCE_ACCURACY_N} N over 0.03-2 N: {INSIGHT}",
    ),
    "frame_rate_hz": (
        float(archive.STEP_RATE),
        "frames sampled at 50 Hz of the camera's 60 Hz: [paper, Minsight Images]",
    ),
}


def effect_loads(loads: minsight.FrameLoads, rubbing: np.ndarray) -> dict[str, minsight.FrameLoads]:
    """Per condition (`CONDITIONS`) the frames' loads: as simulated, one effect alone, or none moving
    (the indentation held at its mean over the `rubbing` frames, every other load at 0)."""
    held = np.full_like(loads.indent_mm, float(np.mean(loads.indent_mm[rubbing])))
    zero = np.zeros_like(loads.indent_mm)
    return {
        "all": loads,
        "indentation": minsight.FrameLoads(loads.indent_mm, zero, zero, zero),
        "shear": minsight.FrameLoads(held, loads.shear_mm, zero, zero),
        "travel": minsight.FrameLoads(held, zero, loads.travel_mm, zero),
        "texture": minsight.FrameLoads(held, zero, zero, loads.slide_mm),
        "still": minsight.FrameLoads(held, zero, zero, zero),
    }


def kept_count(size: Sequence[int]) -> int:
    """How many vectors per frame the paper's filter keeps (`flow.TOP_FRACTION`, as `flow._sparsify`)."""
    return math.ceil(flow.TOP_FRACTION * size[0] * size[1])


def flow_stats(frames: np.ndarray, circle: np.ndarray, method: str) -> dict[str, float]:
    """Dense flow between consecutive `frames` (uint8 (T, H, W, 3)): the mean and 95th percentile of
    its magnitude (px per frame) over the pixels of `circle` ((H, W) bool) and the T - 1 pairs, and
    the mean magnitude of each frame's kept vectors (`kept_count`, over the whole frame as the
    filter takes them)."""
    dense = np.asarray(flow.farneback(frames, method=method))[1:]
    magnitude = np.hypot(dense[..., 0], dense[..., 1])
    inside = magnitude[:, circle]
    k = kept_count(frames.shape[1:3])
    kept = np.sort(magnitude.reshape(len(magnitude), -1), axis=1)[:, -k:]
    return {
        "mean_px": float(inside.mean()),
        "p95_px": float(np.percentile(inside, 95)),
        "kept_px": float(kept.mean()),
    }


def pixel_scale(scene: Scene, size: Sequence[int], contact: Mapping[str, Any]) -> dict[str, float]:
    """Pixels of a `size` frame per mm at the contact's centre: along the rubbing (the wall's
    circumference: the drag and the roll) and per mm of the inner wall's normal displacement
    (the indentation and the texture: where the ray meets the wall moves), from the view of
    `scene`'s day (`minsight._view`, the pixel nearest the centre)."""
    day = minsight.day_state(scene)
    view = minsight._view(scene.seed, int(size[0]), int(size[1]), day.seat_axial_mm, day.seat_rotation_rad)
    dc = np.mod(view.c - contact["centre_c"] + minsight.CIRCUMFERENCE_MM / 2, minsight.CIRCUMFERENCE_MM)
    distance = np.hypot(view.s - contact["centre_s"], dc - minsight.CIRCUMFERENCE_MM / 2)
    i, j = np.unravel_index(np.argmin(np.where(view.valid, distance, np.inf)), distance.shape)
    jac = view.jac_inv[i, j]  # pixel (x, y) per (s, c) mm
    return {
        "tangential_px_per_mm": float(np.hypot(*jac[:, 1])),
        "normal_px_per_mm": float(np.hypot(*(jac @ view.shift_n[i, j]))),
        "pixel": [int(i), int(j)],
    }


def wall_motion(loads: minsight.FrameLoads, contact: Mapping[str, Any], rubbing: np.ndarray) -> dict[str, np.ndarray]:
    """Per effect, how far the wall (or the patch) moves at the contact's centre between consecutive
    rubbing frames, mm: the inner wall's normal displacement for the indentation (the share of the
    outer indentation it keeps, `minsight.inner_profile`) and the texture (its relief's amplitude at
    the wall times the change of its phase's cosine), the inner face's drag for the shear, the patch
    centre's roll for the travel."""
    a, _ = minsight.hertz(cal.GRASP_FORCE_N)
    _, _, share = minsight.inner_profile(round(a * contact["patch"].along, 2))
    ripple = contact["texture_amplitude"] * np.cos(2 * np.pi * loads.slide_mm / contact["texture_wavelength"])
    pairs = rubbing[1:] & rubbing[:-1]
    step = lambda x: np.abs(np.diff(np.asarray(x, np.float64)))[pairs]  # noqa: E731
    return {
        "indentation": step(share * contact["patch"].depth * loads.indent_mm),
        "shear": step(loads.shear_mm),
        "travel": step(loads.travel_mm),
        "texture": step(ripple),
    }


def trial_scene(preset: str, fabric_id: int, day: int, trial_no: int, cycles: int, size) -> Scene:
    """The preset's scene of the trial (`sim.dataset.scene_for`: its estimates, its cloth's history),
    `cycles` rubbing cycles long, with frames of `size`."""
    spec = splits.TrialSpec(fabric_id, day, trial_no, "lab")
    scene = sim_dataset.scene_for(spec, presets.get(preset).dataset, STREAMS)
    return dataclasses.replace(scene, cycles=cycles, image_size=tuple(int(v) for v in size))


def measure(
    scene: Scene, conditions: Sequence[str], method: str, frames: int | None = None, mechanics: bool = True
) -> dict[str, Any]:
    """One trial: per condition and noise (`NOISE`) its flow (`flow_stats`); with `mechanics`, its
    loads' summary, the wall's motion per effect (`wall_motion`: per-frame 95th percentile and
    largest, mm and px) and the camera's scale. `frames`: only the first so many rubbing frames."""
    trial.use_estimates(scene.estimates)
    proc = trial.procedure(scene)
    rng = scene.rng("minsight", "trial")
    contact = minsight.trial_contact(scene, proc.nuisance, rng)  # the trial's patch, as `minsight.render` draws it
    loads = minsight.frame_loads(proc.motion, proc.frame_times, contact)
    rubbing = proc.frame_times >= proc.motion.rubbing_start_s
    if frames is not None:
        rubbing &= np.cumsum(rubbing) <= frames
    first, last = int(np.flatnonzero(rubbing)[0]), int(np.flatnonzero(rubbing)[-1]) + 1
    circle = minsight.no_contact_frame(scene).max(axis=-1) > 0
    out: dict[str, Any] = {"frames": last - first, "flow": {}}
    by_condition = effect_loads(loads, rubbing)
    for name in conditions:
        part = minsight.FrameLoads(
            *(getattr(by_condition[name], f.name)[first:last] for f in dataclasses.fields(loads))
        )
        clean = minsight.physical_frames(scene, part, contact)
        quantised = {
            "noise-free": np.clip(np.rint(clean), 0, 255).astype(np.uint8),
            "shot noise": minsight.quantise(clean, scene.image_size, copy.deepcopy(rng)),  # one set of draws
        }
        out["flow"][name] = {kind: flow_stats(quantised[kind], circle, method) for kind in NOISE}
    if mechanics:
        m = proc.motion
        on = (m.t >= m.rubbing_start_s) & (m.t <= proc.frame_times[last - 1])
        scale = pixel_scale(scene, scene.image_size, contact)
        per_mm = {"indentation": "normal", "shear": "tangential", "travel": "tangential", "texture": "normal"}
        moved = wall_motion(loads, contact, rubbing)
        out.update(
            stick_mm=float(m.slip_width_mm),
            friction=float(m.friction),
            normal_swing_n=float(np.ptp(m.normal_n[on])),
            shear_swing_n=float(np.ptp(m.shear_n[on])),
            shear_swing_mm=float(np.ptp(loads.shear_mm[rubbing])),
            travel_swing_mm=float(np.ptp(loads.travel_mm[rubbing])),
            frames_per_cycle=float(archive.STEP_RATE / rate_hz(m)),
            patch_radius_mm=float(minsight.hertz(cal.GRASP_FORCE_N)[0] * contact["patch"].along),
            texture_amplitude_mm=float(contact["texture_amplitude"]),
            scale=scale,
            wall={
                e: {
                    "p95_mm": float(np.percentile(d, 95)),
                    "max_mm": float(d.max()),
                    "p95_px": float(np.percentile(d, 95) * scale[f"{per_mm[e]}_px_per_mm"]),
                    "max_px": float(d.max() * scale[f"{per_mm[e]}_px_per_mm"]),
                }
                for e, d in moved.items()
            },
        )
    return out


def rate_hz(motion) -> float:
    """The trial's mean stroke rate over its rubbing: upward zero crossings of the thumb's offset per second."""
    t, x = np.asarray(motion.t), np.asarray(motion.finger_mm)
    on = t >= motion.rubbing_start_s
    up = np.flatnonzero(on[1:] & (x[:-1] < 0) & (x[1:] >= 0)) + 1
    if len(up) < 2:
        raise ValueError("the trial rubs fewer than two whole cycles: no stroke rate to measure")
    return float((len(up) - 1) / (t[up[-1]] - t[up[0]]))


def eta_squared(groups: Sequence[Sequence[float]]) -> dict[str, float]:
    """The share of the values' variance between the groups (one per fabric: its trials' values),
    sum of squares between over total, and the share chance alone gives, (k - 1) / (n - 1)."""
    values = np.concatenate([np.asarray(g, np.float64) for g in groups])
    if len(groups) < 2 or len(values) <= len(groups):
        raise ValueError("need at least two groups and more values than groups")
    total = float(np.sum((values - values.mean()) ** 2))
    between = float(sum(len(g) * (np.mean(g) - values.mean()) ** 2 for g in groups))
    return {"share": between / total if total > 0 else 0.0, "chance": (len(groups) - 1) / (len(values) - 1)}


def signal_over_noise(result: Mapping[str, Any], condition: str = "all") -> float:
    """A trial's kept vectors with shot noise under `condition`, over the still contact's with the same noise."""
    f = result["flow"]
    return f[condition]["shot noise"]["kept_px"] / f["still"]["shot noise"]["kept_px"]


def fabrics_of(preset: str) -> list[int]:
    """The preset's fabrics the classifier trains on (class 0 included; new fabrics have test trials only)."""
    return [f for f in presets.get(preset).dataset.fabrics if f not in catalog.NEW_FABRICS]


def summarise(trials: Mapping[int, Sequence[Mapping[str, Any]]]) -> dict[str, Any]:
    """Pooled over the trials of every fabric: per condition and noise the mean of each flow
    statistic and its fabric share (`eta_squared`), per effect the wall's motion, and the signal
    over noise of each condition."""
    groups = list(trials.values())
    every = [r for g in groups for r in g]
    out: dict[str, Any] = {"flow": {}, "wall": {}, "signal_over_noise": {}}
    for name in every[0]["flow"]:
        out["flow"][name] = {
            kind: {
                stat: {
                    "mean": float(np.mean([r["flow"][name][kind][stat] for r in every])),
                    "fabric": eta_squared([[r["flow"][name][kind][stat] for r in g] for g in groups]),
                }
                for stat in ("mean_px", "p95_px", "kept_px")
            }
            for kind in NOISE
        }
        if name != "still":
            ratios = [[signal_over_noise(r, name) for r in g] for g in groups]
            out["signal_over_noise"][name] = {
                "mean": float(np.mean([v for g in ratios for v in g])),
                "min": float(min(v for g in ratios for v in g)),
                "max": float(max(v for g in ratios for v in g)),
            }
    for effect in EFFECTS:
        out["wall"][effect] = {
            stat: {
                "mean": float(np.mean([r["wall"][effect][stat] for r in every])),
                "max": float(np.max([r["wall"][effect][stat] for r in every])),
                "fabric": eta_squared([[r["wall"][effect][stat] for r in g] for g in groups]),
            }
            for stat in ("p95_mm", "max_mm", "p95_px", "max_px")
        }
    return out


def published_comparison(doc: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Per quantity the simulated range (least and largest fabric mean over its trials) beside the
    published figure it is compared with (`PUBLISHED`)."""
    measured = doc["trials_measured"]

    def span(get) -> list[float]:
        means = [float(np.mean([get(r) for r in rs])) for rs in measured.values()]
        return [min(means), max(means)]

    res, minsight_f, insight_f, rate = (PUBLISHED[k][0] for k in PUBLISHED)
    return [
        {
            "quantity": "the inner wall's drag between two frames, p95 (mm)",
            "simulated": span(lambda r: r["wall"]["shear"]["p95_mm"]),
            "published": res,
            "source": PUBLISHED["spatial_resolution_mm"][1],
        },
        {
            "quantity": "the patch's roll along the shell between two frames, p95 (mm)",
            "simulated": span(lambda r: r["wall"]["travel"]["p95_mm"]),
            "published": res,
            "source": PUBLISHED["spatial_resolution_mm"][1],
        },
        {
            "quantity": f"the wall per pixel of a {_size(doc['size'])} frame at the contact (mm)",
            "simulated": span(lambda r: 1 / r["scale"]["tangential_px_per_mm"]),
            "published": res,
            "source": PUBLISHED["spatial_resolution_mm"][1],
        },
        {
            "quantity": "the normal force's swing over the rubbing (N)",
            "simulated": span(lambda r: r["normal_swing_n"]),
            "published": minsight_f,
            "source": PUBLISHED["minsight_force_error_n"][1],
        },
        {
            "quantity": "the tangential load's swing over the rubbing (N)",
            "simulated": span(lambda r: r["shear_swing_n"]),
            "published": insight_f,
            "source": PUBLISHED["insight_force_accuracy_n"][1],
        },
        {
            "quantity": "frames per rubbing cycle",
            "simulated": span(lambda r: r["frames_per_cycle"]),
            "published": rate / cal.CYCLE_HZ,
            "source": PUBLISHED["frame_rate_hz"][1] + f", at the commanded {cal.CYCLE_HZ:g} Hz stroke (an estimate)",
        },
    ]


def run(
    *,
    preset: str = "default",
    rows: Sequence[str] | None = None,
    overrides: Mapping[str, Any] | None = None,
    fabrics: Sequence[int] | None = None,
    trials: Sequence[tuple[int, int]] = TRIALS,
    cycles: int = CYCLES,
    size: tuple[int, int] = SIZE,
    paper_size: tuple[int, int] | None = PAPER_SIZE,
    paper_frames: int = PAPER_FRAMES,
    where: Location = Location(),
) -> dict[str, Any]:
    """Measure every fabric's trials (`measure`), summarise them (`summarise`) and write
    results/flow_budget.{md,json}; returns the JSON. `rows` and `overrides` are what `reproduce`
    passes every study: this one has no rows, and of the `Config` fields only `flow_method` has a
    say (who computes the flow); the others are recorded. `paper_size` None leaves the check at the
    paper's flow resolution out."""
    if rows:
        raise UserError(f"{STUDY} has no rows to choose, got --rows={','.join(rows)}")
    if where.data_dir:
        raise UserError(f"{STUDY} measures the simulator's frames: --data_dir has no say in it")
    overrides = dict(overrides or {})
    method = Config.from_preset(preset, **overrides).flow_method
    fabrics = list(fabrics if fabrics is not None else fabrics_of(preset))
    t0 = time.perf_counter()
    measured = {
        f: [measure(trial_scene(preset, f, d, k, cycles, size), CONDITIONS, method) for d, k in trials] for f in fabrics
    }
    paper = None
    if paper_size is not None:
        d, k = trials[0]
        paper = {
            f: measure(trial_scene(preset, f, d, k, cycles, paper_size), ("all", "still"), method, paper_frames, False)
            for f in fabrics
        }
    doc = {
        **documents.header(
            STUDY,
            module=__name__,
            command=where.command,
            preset=preset,
            overrides=overrides,
            flow_method=method,
            fabrics=fabrics,
            trials=[list(t) for t in trials],
            cycles=cycles,
            size=list(size),
            paper_size=None if paper_size is None else list(paper_size),
            paper_frames=paper_frames,
            kept_per_frame={
                "size": kept_count(size),
                "paper_size": None if paper_size is None else kept_count(paper_size),
            },
            wall_s=time.perf_counter() - t0,
        ),
        "trials_measured": {str(f): r for f, r in measured.items()},
        "summary": summarise(measured),
        "at_paper_size": None
        if paper is None
        else {
            "trials": {str(f): r for f, r in paper.items()},
            "signal_over_noise": {
                "mean": float(np.mean([signal_over_noise(r) for r in paper.values()])),
                "min": float(min(signal_over_noise(r) for r in paper.values())),
                "max": float(max(signal_over_noise(r) for r in paper.values())),
            },
        },
    }
    doc["headline"] = headline(doc)
    doc["published"] = published_comparison(doc)
    return results_files.write(where.results_dir(), doc, markdown)


def headline(doc: Mapping[str, Any]) -> dict[str, Any]:
    """The numbers docs/simulator.md quotes: at the budget's size, the kept vectors of the whole
    stroke over the still contact's noise alone, and the fabric's share of their per-trial
    magnitude against chance; at the paper's flow resolution, the same signal over noise."""
    s = doc["summary"]
    kept = s["flow"]["all"]["shot noise"]["kept_px"]
    return {
        "signal_over_noise": s["signal_over_noise"]["all"]["mean"],
        "fabric_share": kept["fabric"]["share"],
        "fabric_share_chance": kept["fabric"]["chance"],
        "paper_size_signal_over_noise": None
        if doc["at_paper_size"] is None
        else doc["at_paper_size"]["signal_over_noise"]["mean"],
    }


def gap_sentence(doc: Mapping[str, Any]) -> str:
    """The headline in words (`headline`)."""
    h, size = doc["headline"], _size(doc["size"])
    text = (
        f"At {size}, the vectors the paper's filter keeps from the whole simulated stroke with the camera's "
        f"noise are **{h['signal_over_noise']:.2f} times** those of a still contact under the same noise "
        f"(mean over trials; 1: noise alone), and the fabric explains {100 * h['fabric_share']:.0f} % of their "
        f"per-trial magnitude (chance alone: {100 * h['fabric_share_chance']:.0f} %)."
    )
    if h["paper_size_signal_over_noise"] is not None:
        p = doc["at_paper_size"]["signal_over_noise"]
        d, k = doc["trials"][0]
        text += (
            f" At the paper's flow resolution, {_size(doc['paper_size'])}, the same ratio is "
            f"**{h['paper_size_signal_over_noise']:.2f}** ({p['min']:.2f}-{p['max']:.2f} over the fabrics; "
            f"day {d} trial {k}, its first {doc['paper_frames']} rubbing frames)."
        )
    return text


def published_sentence(doc: Mapping[str, Any]) -> str:
    """What the comparison with the published figures says, in words (`published_comparison`'s rows)."""
    drag, roll, pitch, normal, shear, _ = doc["published"]
    return (
        f"As a force the stroke is within Minsight's reach: its tangential load swings by "
        f"{shear['simulated'][0] / shear['published']:.0f}-{shear['simulated'][1] / shear['published']:.0f} "
        f"times Insight's force accuracy (its normal force by at most "
        f"{normal['simulated'][1] / normal['published']:.2f} of Minsight's force error). As image motion at "
        f"{_size(doc['size'])} it stays under about a pixel per frame: between two frames the drag moves the "
        f"wall by {drag['simulated'][0] / drag['published']:.2f}-"
        f"{drag['simulated'][1] / drag['published']:.2f} of Insight's spatial resolution and the patch rolls by "
        f"{roll['simulated'][0] / roll['published']:.1f}-{roll['simulated'][1] / roll['published']:.1f} of it, "
        f"while one pixel of a {_size(doc['size'])} frame spans {pitch['simulated'][0] / pitch['published']:.1f}-"
        f"{pitch['simulated'][1] / pitch['published']:.1f} of it at the contact."
    )


def _size(size: Sequence[int]) -> str:
    return f"{size[0]}x{size[1]}"


def _share(e: Mapping[str, float]) -> str:
    return f"{100 * e['share']:.0f} % (chance {100 * e['chance']:.0f} %)"


def markdown(doc: dict[str, Any]) -> str:
    """The page: what was measured and how, the gap in one number, then each table."""
    size = _size(doc["size"])
    return "\n".join(
        [
            *_intro_markdown(doc, size),
            *_flow_markdown(doc, size),
            *_wall_markdown(doc, size),
            *_fabric_markdown(doc, size),
            *_published_markdown(doc),
            *_paper_size_markdown(doc),
        ]
    )


def _intro_markdown(doc: dict[str, Any], size: str) -> list[str]:
    """The title, where the numbers come from, what each condition is, and the gap in one number."""
    n_trials = len(doc["trials"])
    trials = ", ".join(f"day {d} trial {k}" for d, k in doc["trials"])
    return [
        f"# {TITLE}",
        "",
        documents.header_markdown(doc, f"{doc['wall_s']:.0f} s"),
        "What each simulated effect of the stroke does to Minsight's imaged wall, and how much optical flow "
        f"a frame pair shows of it, on {len(doc['fabrics'])} fabrics (the preset's classes, class 0 no fabric), "
        f"{n_trials} lab trials each ({trials}), each {doc['cycles']} rubbing cycles long, over its rubbing "
        f"frames (closing excluded). Frames {size} (the paper's image input, the default preset's frames and "
        f"flow); dense Farneback flow by `{doc['flow_method']}` between consecutive frames. Conditions: every "
        "load as simulated (all), one load alone with the others held (the indentation at its mean over the "
        "rubbing frames, the drag, roll and slide at 0), none moving (still: the contact present). Each "
        "condition's frames noise-free (rounded to whole DN) and with the camera's shot noise, the same "
        "draws in every condition. Kept: the mean magnitude of the vectors the paper's filter keeps, the "
        f"top 0.1 % of each frame ({doc['kept_per_frame']['size']} of {doc['size'][0] * doc['size'][1]} at "
        f"{size}). Fabric share: of the per-trial values' variance, the share between fabrics (eta squared), "
        "beside what chance alone gives. How it is computed: `fabricjax/studies/diagnostics/flow_budget.py`.",
        "",
        "## The gap in one number",
        "",
        gap_sentence(doc),
    ]


def _flow_markdown(doc: dict[str, Any], size: str) -> list[str]:
    """Optical flow per condition: its statistics, their fabric shares and the signal over noise."""
    s = doc["summary"]
    return [
        "",
        f"## Optical flow per condition, {size}",
        "",
        "Mean over every trial of each statistic (px per frame), and the share of its per-trial variance "
        "the fabric explains. Signal over noise: the condition's kept vectors with shot noise over the "
        "still contact's (mean, least and largest over trials).",
        "",
        results_files.markdown_table(
            [
                "Condition",
                "Noise-free: mean",
                "p95",
                "kept",
                "kept: fabric share",
                "Shot noise: mean",
                "p95",
                "kept",
                "kept: fabric share",
                "Signal over noise",
            ],
            [
                [
                    name,
                    *(
                        v
                        for kind in NOISE
                        for v in (
                            f"{f[kind]['mean_px']['mean']:.4f}",
                            f"{f[kind]['p95_px']['mean']:.4f}",
                            f"{f[kind]['kept_px']['mean']:.3f}",
                            _share(f[kind]["kept_px"]["fabric"]),
                        )
                    ),
                    "1 (by definition)"
                    if name == "still"
                    else "{mean:.2f} ({min:.2f}-{max:.2f})".format(**s["signal_over_noise"][name]),
                ]
                for name, f in s["flow"].items()
            ],
        ),
    ]


def _wall_markdown(doc: dict[str, Any], size: str) -> list[str]:
    """The wall's own motion per effect, in mm and in pixels."""
    s = doc["summary"]
    return [
        "## The wall's own motion per effect",
        "",
        "Between consecutive rubbing frames, at the contact's centre: the inner wall's normal displacement "
        "(indentation, texture), its drag (shear), the patch centre's roll along the shell (travel); in mm and "
        f"in pixels of a {size} frame by the camera's scale at the centre. Per trial its 95th percentile and "
        "largest over the frames; mean and largest over trials, and the fabric's share of the per-trial 95th "
        "percentile.",
        "",
        results_files.markdown_table(
            [
                "Effect",
                "p95 [mm/frame]",
                "largest [mm/frame]",
                "p95 [px/frame]",
                "largest [px/frame]",
                "p95: fabric share",
            ],
            [
                [
                    effect,
                    f"{w['p95_mm']['mean']:.4f} (max {w['p95_mm']['max']:.4f})",
                    f"{w['max_mm']['mean']:.4f} (max {w['max_mm']['max']:.4f})",
                    f"{w['p95_px']['mean']:.3f} (max {w['p95_px']['max']:.3f})",
                    f"{w['max_px']['mean']:.3f} (max {w['max_px']['max']:.3f})",
                    _share(w["p95_mm"]["fabric"]),
                ]
                for effect, w in s["wall"].items()
            ],
        ),
    ]


def _fabric_markdown(doc: dict[str, Any], size: str) -> list[str]:
    """Per fabric: the stick, the load and wall swings, the texture and the kept flow; the camera's scale."""
    n_trials = len(doc["trials"])
    scale = next(iter(doc["trials_measured"].values()))[0]["scale"]
    return [
        f"## Per fabric, {size}",
        "",
        f"Mean over the fabric's {n_trials} trials (± SD over them where it moves): the stick length "
        "mu F_n / k_t, the swing over the rubbing of the normal and tangential force (N) and of the inner "
        "wall's drag and the patch's roll (mm), the contact's patch radius, the coarse texture's amplitude "
        "at the wall, and the kept flow vectors of the whole stroke noise-free and with shot noise, and "
        "those of the still contact under the same noise.",
        "",
        results_files.markdown_table(
            [
                "Fabric",
                "stick [mm]",
                "normal swing [N]",
                "shear swing [N]",
                "drag swing [mm]",
                "roll swing [mm]",
                "patch radius [mm]",
                "texture [um]",
                "kept, noise-free [px]",
                "kept, shot noise [px]",
                "kept, still + noise [px]",
            ],
            [_fabric_row(int(f), rs) for f, rs in doc["trials_measured"].items()],
        ),
        f"The camera's scale at the first trial's contact centre, {size}: "
        f"{scale['tangential_px_per_mm']:.2f} px per mm along the rubbing "
        f"({1 / scale['tangential_px_per_mm']:.2f} mm per pixel), {scale['normal_px_per_mm']:.2f} px per mm of "
        "the inner wall's normal displacement.",
    ]


def _published_markdown(doc: dict[str, Any]) -> list[str]:
    """The simulated ranges against Minsight's published figures."""
    return [
        "",
        "## Against Minsight's published figures",
        "",
        "The simulated range is the least and largest fabric mean (over its trials).",
        "",
        results_files.markdown_table(
            ["Quantity", "Simulated", "Published", "Source"],
            [
                [c["quantity"], f"{c['simulated'][0]:.3g}-{c['simulated'][1]:.3g}", f"{c['published']:g}", c["source"]]
                for c in doc["published"]
            ],
        ),
        published_sentence(doc),
    ]


def _paper_size_markdown(doc: dict[str, Any]) -> list[str]:
    """Each fabric's first trial at the paper's flow resolution, where it was measured."""
    if doc["at_paper_size"] is None:
        return []
    return [
        "",
        f"## At the paper's flow resolution, {_size(doc['paper_size'])}",
        "",
        f"The first trial of each fabric, its first {doc['paper_frames']} rubbing frames; kept: the top "
        f"0.1 % of each frame ({doc['kept_per_frame']['paper_size']} vectors).",
        "",
        results_files.markdown_table(
            [
                "Fabric",
                "all, noise-free: p95",
                "kept",
                "all, shot noise: p95",
                "kept",
                "still + noise: kept",
                "Signal over noise",
            ],
            [
                [
                    f"{f} {catalog.fabric(int(f)).name}",
                    f"{r['flow']['all']['noise-free']['p95_px']:.4f}",
                    f"{r['flow']['all']['noise-free']['kept_px']:.3f}",
                    f"{r['flow']['all']['shot noise']['p95_px']:.4f}",
                    f"{r['flow']['all']['shot noise']['kept_px']:.3f}",
                    f"{r['flow']['still']['shot noise']['kept_px']:.3f}",
                    f"{signal_over_noise(r):.2f}",
                ]
                for f, r in doc["at_paper_size"]["trials"].items()
            ],
        ),
    ]


def _fabric_row(fabric_id: int, rs: Sequence[Mapping[str, Any]]) -> list[str]:
    def pm(values, digits):
        v = np.asarray(values, np.float64)
        return f"{v.mean():.{digits}f} ± {v.std(ddof=1):.{digits}f}" if len(v) > 1 else f"{v.mean():.{digits}f}"

    kept = lambda name, kind: [r["flow"][name][kind]["kept_px"] for r in rs]  # noqa: E731
    return [
        f"{fabric_id} {catalog.fabric(fabric_id).name}",
        pm([r["stick_mm"] for r in rs], 2),
        pm([r["normal_swing_n"] for r in rs], 3),
        pm([r["shear_swing_n"] for r in rs], 3),
        pm([r["shear_swing_mm"] for r in rs], 2),
        pm([r["travel_swing_mm"] for r in rs], 2),
        pm([r["patch_radius_mm"] for r in rs], 2),
        pm([1e3 * r["texture_amplitude_mm"] for r in rs], 2),
        pm(kept("all", "noise-free"), 3),
        pm(kept("all", "shot noise"), 3),
        pm(kept("still", "shot noise"), 3),
    ]
