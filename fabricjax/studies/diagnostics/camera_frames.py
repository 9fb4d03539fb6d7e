"""What Minsight's camera sees of a stroke: one moment on four fabrics, and on three days of one.

    python -m experiments.camera_frames --results=results

Minsight's camera looks at the inside of the silicone fingertip (`sim/minsight.py`); a model reads
its frames minus the session's no-contact reference (`Config.image_reference="session"`). This
study draws that difference so that a reader can judge by eye what the contact changes, and asks
whether a fabric changes it more than a new recording day does.

The moment: in each trial, the camera frame of rubbing cycle `CYCLE` (the second) at which the
thumb's lateral displacement (`Motion.finger_mm`) is largest (`moment`): the same point of the stroke in
every trial, each at its own time. The trials: trial 0 (lab) of each of `FABRICS` (a thin smooth
weave, denim, fleece, corduroy) on day 1, and of denim (`DAY_FABRIC`) on each of `DAYS` (the
paper's two training days and its test day), each scene as the preset simulates it
(`sim.dataset.scene_for`: its cycles per trial, its estimates in force). Each panel is the
noise-free frame (`minsight.stroke_frames`, with the trial's contact draws) minus its day's
noise-free no-contact frame (`minsight.no_contact_frame`, what the session's averaged reference
converges to), both rendered at each of `SIZES` (30x40, the default preset's model input; 60x80,
its frames; 308x410, the paper's), and shown as the mean of the three colour
channels' differences. The camera's shot noise is left out, so that the form of the difference
is visible; its level at each size is stated beside it (`noise_levels`).

The figure (`plots.plot_difference_panels`, a grid about 1000 px wide): at `FIGURE_SIZE` the four
fabrics as rendered, the same smoothed (`smoothed`: a Gaussian of `SMOOTH_PX` pixels at 60x80, the
same extent on the wall at every size), denim's three days smoothed, and at `DETAIL_SIZE` denim
and polar fleece (`DETAIL_FABRICS`) as rendered and smoothed. The speckle of the panels as
rendered is the wall's flake grain (`minsight._flake_table`) moving under the pixels where the
contact pushes the wall toward the camera: the render warps the resting wall's image by the
contact's shift (`minsight.physical_frames`), and a sub-pixel shift of a grain that varies from
pixel to pixel changes every pixel; at 308x410 no pixel averages it (smaller sizes are rendered at
twice their size and averaged down), so it is largest there. The smoothed view leaves the
contact's own form.

Numbers, all from the panels' arrays: per panel its largest |difference|, its RMS over the pixels
and its smoothed RMS; per size, the RMS difference between two panels (`pair_rms`), pooled over
the 6 pairs of fabrics and over the 3 pairs of denim's days (`compare`), as rendered and smoothed,
and which is larger; and how few pixels hold half of the fabrics' squared difference
(`concentration`), the number behind the sentence this page shares with the day-shift page
(`camera_variation.RECONCILE`). Both kinds of pair differ in the trial's own draws too (contact
place, fold, speed), so the day pairs hold the trial-to-trial variation of one fabric besides the
day's camera.
"""

from __future__ import annotations

import itertools
import time
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from scipy import ndimage

from fabricjax import catalog, presets
from fabricjax.errors import UserError
from fabricjax.reporting import plots, results_files
from fabricjax.sim import Scene, minsight, trial
from fabricjax.sim import dataset as sim_dataset
from fabricjax.sim.motion import Motion
from fabricjax.store import archive, atomic, splits
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import camera_variation, documents

STUDY = "camera_frames"
TITLE, PAPER = "What Minsight's camera sees of a stroke", "not in the paper"
FABRICS = (12, 1, 10, 9)  # real silk, cotton denim, polar fleece, corduroy
DAY_FABRIC = 1  # cotton denim
DAYS = (1, 2, 3)  # the paper's training days and its test day
SIZES = ((30, 40), (60, 80), (308, 410))  # the default model's input, the default preset's frames, the paper's
FIGURE_SIZE, DETAIL_SIZE = (60, 80), (308, 410)  # the figure's panels; the size whose speckle it shows beside
SMOOTH_PX = 1.5  # the smoothed view: a Gaussian of this SD in pixels at 60x80, the same extent on the wall at any size
DETAIL_FABRICS = (DAY_FABRIC, 10)  # shown at DETAIL_SIZE: denim, and polar fleece, whose patch moves the wall most
HALF = 0.5  # `concentration`: the share of the fabrics' squared difference whose pixels are counted
CYCLE = 2  # the rubbing cycle whose moment is shown: past the first stroke's start from rest
STREAMS = ("audio", "proprio", "images")
LABEL = "frame - session reference (DN)"
CHANNELS = "mean of the R, G and B differences"


def moment(motion: Motion, frame_times: np.ndarray, cycle: int = CYCLE) -> int:
    """Index of the frame (of `frame_times`, s) within rubbing cycle `cycle` (1: the first) at which
    the thumb is furthest out (largest `finger_mm`). A stroke goes out first, so a cycle starts
    where `finger_mm` crosses zero upward after rubbing starts, the first at the start itself."""
    t, x = np.asarray(motion.t), np.asarray(motion.finger_mm)
    rubbing = t[1:] >= motion.rubbing_start_s
    up = np.flatnonzero(rubbing & (x[:-1] < 0) & (x[1:] >= 0)) + 1
    starts = np.concatenate([[motion.rubbing_start_s], t[up]])
    if cycle < 1 or len(starts) <= cycle:
        raise ValueError(f"rubbing cycle {cycle} is not in this trial: it rubs {len(starts) - 1} whole cycles")
    frame_times = np.asarray(frame_times)
    inside = np.flatnonzero((frame_times >= starts[cycle - 1]) & (frame_times < starts[cycle]))
    if not len(inside):
        raise ValueError(f"no camera frame falls within rubbing cycle {cycle}")
    return int(inside[np.argmax(np.interp(frame_times[inside], t, x))])


def shown(difference: np.ndarray) -> np.ndarray:
    """(h, w) float64: what a panel shows of a (h, w, 3) difference in DN (`CHANNELS`)."""
    return np.asarray(difference, np.float64).mean(axis=-1)


def pair_rms(images: Sequence[np.ndarray]) -> float:
    """Root mean square over the pixels and over every pair of `images` of their difference."""
    pairs = list(itertools.combinations(images, 2))
    if not pairs:
        raise ValueError("need at least two images to compare")
    return float(np.sqrt(np.mean([np.mean((a - b) ** 2) for a, b in pairs])))


def compare(fabrics: Sequence[np.ndarray], days: Sequence[np.ndarray]) -> dict[str, Any]:
    """The RMS difference between the fabrics' panels and between one fabric's days' panels (one
    size), and which is larger."""
    f, d = pair_rms(fabrics), pair_rms(days)
    return {
        "fabric_rms_dn": f,
        "fabric_pairs": len(fabrics) * (len(fabrics) - 1) // 2,
        "day_rms_dn": d,
        "day_pairs": len(days) * (len(days) - 1) // 2,
        "fabric_over_day": f / d if d > 0 else None,
        "larger": "fabric" if f > d else "day" if d > f else "neither",
    }


def smoothed(image: np.ndarray) -> np.ndarray:
    """A panel (h, w) smoothed by a Gaussian of `SMOOTH_PX` pixels at 60x80 (scaled with the width,
    so the same extent on the wall at any size; 0 outside the frame): the grain's speckle averages
    out, the contact's smooth form stays."""
    return ndimage.gaussian_filter(np.asarray(image, np.float64), SMOOTH_PX * image.shape[1] / 80, mode="constant")


def panel_numbers(image: np.ndarray) -> dict[str, float]:
    return {
        "max_abs_dn": float(np.abs(image).max()),
        "rms_dn": float(np.sqrt(np.mean(image**2))),
        "smoothed_rms_dn": float(np.sqrt(np.mean(smoothed(image) ** 2))),
    }


def concentration(images: Sequence[np.ndarray], filled: np.ndarray, share: float = HALF) -> float:
    """The fewest pixels, as a share of those the shell fills (`filled`, (h, w) bool), that hold
    `share` of the squared difference between `images`, summed over every pair: how few pixels
    carry what tells the panels apart."""
    pairs = list(itertools.combinations(images, 2))
    if not pairs:
        raise ValueError("need at least two images to compare")
    sq = np.sum([(np.asarray(a, np.float64) - b) ** 2 for a, b in pairs], axis=0)[filled]
    ordered = np.sort(sq)[::-1]
    if ordered.sum() <= 0:
        return float("nan")
    held = np.cumsum(ordered) / ordered.sum()
    return float((np.searchsorted(held, share - 1e-12) + 1) / len(ordered))


def noise_levels(reference: np.ndarray, size: tuple[int, int]) -> dict[str, float]:
    """The camera's shot noise (DN) at `size` over the pixels the shell fills (no-contact frame
    above 0 DN), per pixel and channel of one frame (`minsight._noise_sigma`), and of what a panel
    shows were the frames recorded: the mean of three channels (sigma / sqrt 3) of one frame minus a
    reference averaged over `archive.REFERENCE_FRAMES` frames. Also how many pixels of the
    no-contact frame lie below 0 DN, and its least value."""
    sigma = minsight._noise_sigma(np.asarray(reference, np.float32), size)
    filled = np.asarray(reference).max(axis=-1) > 0
    per_channel = sigma[filled]
    panel = np.sqrt(np.mean(per_channel**2, axis=-1) / 3 * (1 + 1 / archive.REFERENCE_FRAMES))
    return {
        "channel_median_dn": float(np.median(per_channel)),
        "channel_max_dn": float(per_channel.max()),
        "panel_median_dn": float(np.median(panel)),
        # light cannot be negative: such pixels differ from any frame without any contact
        "reference_below_zero_px": int((np.asarray(reference).min(axis=-1) < 0).sum()),
        "reference_min_dn": float(np.asarray(reference).min()),
    }


def _scene(preset: str, fabric_id: int, day: int) -> Scene:
    spec = splits.TrialSpec(fabric_id, day, 0, "lab")
    return sim_dataset.scene_for(spec, presets.get(preset).dataset, STREAMS)


def render(scene: Scene, sizes: Sequence[tuple[int, int]]) -> tuple[dict[str, Any], dict, dict]:
    """The chosen moment of `scene`'s trial ({frame, t_s, finger_mm, normal_n, shear_n}), and per
    size the (h, w, 3) difference from the no-contact frame and the no-contact frame itself."""
    trial.use_estimates(scene.estimates)
    proc = trial.procedure(scene)
    k = moment(proc.motion, proc.frame_times)
    t = proc.frame_times[k : k + 1]
    m = proc.motion
    when = {
        "frame": k,
        "t_s": float(t[0]),
        **{f: float(np.interp(t[0], m.t, getattr(m, f))) for f in ("finger_mm", "normal_n", "shear_n")},
    }
    diffs, refs = {}, {}
    for size in sizes:
        frame = minsight.stroke_frames(scene, m, t, proc.nuisance, scene.rng("minsight", "trial"), size=size)[0]
        refs[size] = minsight.no_contact_frame(scene, size=size)
        diffs[size] = frame - refs[size]
    return when, diffs, refs


def _name(fabric_id: int) -> str:
    return catalog.fabric(fabric_id).name


def _size(size: Sequence[int]) -> str:
    return f"{size[0]}x{size[1]}"


def measure(
    preset: str, sizes: Sequence[tuple[int, int]]
) -> tuple[dict, list[dict[str, Any]], dict[str, Any], dict[str, Any]]:
    """Render every panel at every size and compare them: (the panels' images by (scene, size),
    each panel's numbers, the fabrics against the days per size, the camera's noise per size)."""
    keys = [*((f, 1) for f in FABRICS), *((DAY_FABRIC, d) for d in DAYS if (DAY_FABRIC, d) != (DAY_FABRIC, 1))]
    rendered = {key: render(_scene(preset, *key), sizes) for key in keys}
    images = {(key, size): shown(rendered[key][1][size]) for key in keys for size in sizes}

    panels, comparison, noise = [], {}, {}
    for size in sizes:
        block = [((f, 1), "fabric") for f in FABRICS] + [((DAY_FABRIC, d), "day") for d in DAYS]
        for (fabric, day), kind in block:
            panels.append(
                {
                    "block": kind,
                    "fabric": fabric,
                    "name": _name(fabric),
                    "day": day,
                    "size": list(size),
                    **rendered[(fabric, day)][0],
                    **panel_numbers(images[((fabric, day), size)]),
                }
            )
        fabric_images = [images[((f, 1), size)] for f in FABRICS]
        day_images = [images[((DAY_FABRIC, d), size)] for d in DAYS]
        reference = rendered[(DAY_FABRIC, 1)][2][size]
        comparison[_size(size)] = {
            **compare(fabric_images, day_images),
            "smoothed": compare([smoothed(i) for i in fabric_images], [smoothed(i) for i in day_images]),
            "fabric_half_px": concentration(fabric_images, np.asarray(reference).max(axis=-1) > 0),
        }
        noise[_size(size)] = noise_levels(reference, size)
    return images, panels, comparison, noise


def draw(path: Path, images: Mapping, figure: tuple[int, int], detail, vmax: float, linear: float) -> Path:
    """results/camera_frames.png: the fabrics as rendered and smoothed, denim's days smoothed, at the
    `figure` size, and two fabrics at the `detail` size (None: not drawn), on one colour scale."""
    short = {f: _name(f).split(" ")[-1] for f in {*FABRICS, DAY_FABRIC}}  # "silk", "denim", "fleece", "corduroy"
    denim = short[DAY_FABRIC]
    rows = [
        [(f"{short[f]}, day 1", images[((f, 1), figure)]) for f in FABRICS],
        [(f"{short[f]}, day 1", smoothed(images[((f, 1), figure)])) for f in FABRICS],
        [(f"{denim}, day {d}", smoothed(images[((DAY_FABRIC, d), figure)])) for d in DAYS],
    ]
    row_labels = [f"{_size(figure)}, as rendered", f"{_size(figure)}, smoothed", f"{_size(figure)}, smoothed"]
    if detail is not None:
        rows.append(
            [
                (f"{short[f]}, day 1{view}", image)
                for f in DETAIL_FABRICS
                for view, image in (
                    (", as rendered", images[((f, 1), detail)]),
                    (", smoothed", smoothed(images[((f, 1), detail)])),
                )
            ]
        )
        row_labels.append(_size(detail))
    return plots.plot_difference_panels(
        path,
        rows,
        row_labels,
        vmax,
        linear,
        LABEL,
        f"Minsight frame - session reference, noise-free, at the thumb's furthest reach in rubbing cycle {CYCLE}\n"
        f"(mean of R, G, B; the speckle is the wall's grain moving under the contact; smoothed: "
        f"Gaussian, SD {SMOOTH_PX:g} px at 60x80)",
    )


def run(
    *,
    preset: str = "default",
    rows: Sequence[str] | None = None,
    overrides: Mapping[str, Any] | None = None,
    sizes: Sequence[tuple[int, int]] = SIZES,
    where: Location = Location(),
) -> dict[str, Any]:
    """Render every panel, compare them, draw results/camera_frames.png and write
    results/camera_frames.{md,json}; returns the JSON. `rows` and `overrides` are what `reproduce`
    passes every study: this one has no rows, and `Config` fields (training settings) do not change
    the simulator's frames, so the overrides are only recorded."""
    if rows:
        raise UserError(f"{STUDY} has no rows to choose, got --rows={','.join(rows)}")
    if where.data_dir:
        raise UserError(f"{STUDY} draws the simulator's frames: --data_dir has no say in it")
    presets.get(preset)
    sizes = [tuple(int(v) for v in s) for s in sizes]
    t0 = time.perf_counter()
    images, panels, comparison, noise = measure(preset, sizes)
    figure = FIGURE_SIZE if FIGURE_SIZE in sizes else sizes[0]
    detail = DETAIL_SIZE if DETAIL_SIZE in sizes and DETAIL_SIZE != figure else None
    # the colour scale: linear up to the noise a recorded panel of the figure's size would carry, so
    # that what lies below the camera's noise is not stretched, logarithmic beyond up to the largest |difference|
    linear = noise[_size(figure)]["panel_median_dn"]
    vmax = max(max(p["max_abs_dn"] for p in panels if tuple(p["size"]) in (figure, detail)), 10 * linear)
    with atomic.together():  # the figure, Markdown and JSON of this run, or none of them
        png = draw(where.results_dir() / f"{STUDY}.png", images, figure, detail, vmax, linear)
        doc = {
            **documents.header(
                STUDY,
                module=__name__,
                command=where.command,
                preset=preset,
                overrides=dict(overrides or {}),
                fabrics=list(FABRICS),
                day_fabric=DAY_FABRIC,
                days=list(DAYS),
                sizes=[list(s) for s in sizes],
                figure_size=list(figure),
                detail_size=list(detail) if detail else None,
                smooth_px=SMOOTH_PX,
                cycle=CYCLE,
                channels=CHANNELS,
                colour_limit_dn=vmax,
                colour_linear_dn=linear,
                wall_s=time.perf_counter() - t0,
            ),
            "panels": panels,
            "comparison": comparison,
            "noise": noise,
        }
        return results_files.write(where.results_dir(), doc, markdown, [png])


def verdict(c: Mapping[str, Any]) -> str:
    """Which RMS difference is larger, in words."""
    if c["larger"] == "neither":
        return "neither is larger"
    ratio = f" ({c['fabric_over_day']:.2f} times)" if c["fabric_over_day"] is not None else ""
    return (
        f"the fabrics differ more than denim's days{ratio}"
        if c["larger"] == "fabric"
        else (f"denim's days differ more than the fabrics{ratio}")
    )


def markdown(doc: dict[str, Any]) -> str:
    """The page: the figure and how it is drawn, the fabrics against the days, each panel, the noise."""
    figure = _size(doc["figure_size"])
    smooth = f"a Gaussian of SD {doc['smooth_px']:g} pixels at 60x80, the same extent on the wall at every size"
    model = _size(presets.get(doc["preset"]).training.get("image_size", doc["figure_size"]))
    return "\n".join(
        [
            *_figure_markdown(doc, figure, smooth),
            *_comparison_markdown(doc, smooth, model),
            *_panels_markdown(doc),
            *_noise_markdown(doc),
        ]
    )


def _figure_markdown(doc: dict[str, Any], figure: str, smooth: str) -> list[str]:
    """The title, where the numbers come from, the figure and what its panels show."""
    days = ", ".join(str(d) for d in doc["days"])
    fabrics = ", ".join(f"{f} {_name(f)}" for f in doc["fabrics"])
    detail = doc["detail_size"] and _size(doc["detail_size"])
    return [
        f"# {TITLE}",
        "",
        documents.header_markdown(doc, f"{doc['wall_s']:.0f} s"),
        f"![Minsight frames minus the session reference]({STUDY}.png)",
        "",
        f"What Minsight's camera sees at one moment of a stroke: the frame of rubbing cycle {doc['cycle']} at "
        "which the thumb's lateral displacement (`motion.finger_mm`) is largest, minus the same day's "
        "no-contact frame (what the session's reference converges to), each panel the "
        f"{doc['channels']}. Rows of the figure, at {figure}: trial 0 (lab) of each of the fabrics {fabrics} "
        f"on day 1 as rendered; the same smoothed; {_name(doc['day_fabric'])} on days {days} smoothed"
        + (
            f"; and at {detail}, {' and '.join(_name(f) for f in DETAIL_FABRICS)} (day 1) as rendered and smoothed"
            if detail
            else ""
        )
        + ". "
        "The speckle is the wall's grain, its aluminium flakes (`FLAKE_CONTRAST`, cells of "
        "`FLAKE_SIZE_MM`), moving under the pixels where the contact pushes the wall toward the camera: "
        "the render warps the resting wall's image (`minsight.physical_frames`), so a shift of a fraction "
        "of a pixel changes each pixel by the grain's contrast times the shift. At 308x410 each pixel sees "
        "a few flake cells and nothing averages them (smaller frames are rendered at twice their size and "
        f"averaged down), so the speckle is largest there. The smoothed view ({smooth}) averages the grain "
        "out and leaves the contact's own form: the per-panel table gives both RMS. "
        "One colour scale for all panels: linear within "
        f"±{doc['colour_linear_dn']:.2f} DN (the noise a recorded {figure} panel would carry, last table), "
        f"logarithmic beyond it up to ±{doc['colour_limit_dn']:.1f} DN (the largest |difference| of any panel "
        "shown). The frames are noise-free: the camera's shot noise is left out, so that the form of the "
        "difference is visible; its level is in the last table. Every trial is the preset's own scene, each "
        "at its own frame time.",
        "",
    ]


def _comparison_markdown(doc: dict[str, Any], smooth: str, model: str) -> list[str]:
    """The fabrics against denim's days, per size, and the sentence shared with the day shift's page."""
    compared = doc["comparison"]
    return [
        "## Fabric against day",
        "",
        "RMS over the pixels of the difference between two panels of one size, pooled (root mean square) "
        "over the pairs: the fabrics' pairs (day 1) and the pairs of denim's days, as rendered and smoothed "
        f"({smooth}). Both also differ in the trial's own draws (where the contact lands, the fold, the "
        f"speed). {model} is what the preset's model reads (`Config.image_size`). The last column: the "
        "fewest pixels, of those the shell fills, that hold half of the fabrics' squared difference.",
        "",
        results_files.markdown_table(
            [
                "Size",
                "Fabrics: RMS difference [DN]",
                "Denim's days: RMS difference [DN]",
                "Larger",
                "Smoothed: fabrics [DN]",
                "Smoothed: days [DN]",
                "Smoothed: larger",
                "Pixels holding half the fabrics' difference [%]",
            ],
            [
                [
                    size,
                    f"{c['fabric_rms_dn']:.2f} ({c['fabric_pairs']} pairs)",
                    f"{c['day_rms_dn']:.2f} ({c['day_pairs']} pairs)",
                    verdict(c),
                    f"{c['smoothed']['fabric_rms_dn']:.3f}",
                    f"{c['smoothed']['day_rms_dn']:.3f}",
                    verdict(c["smoothed"]),
                    f"{100 * c['fabric_half_px']:.1f}",
                ]
                for size, c in compared.items()
            ],
        ),
        "## Against day_shift",
        "",
        camera_variation.RECONCILE
        + (
            f" Here, at {model}, half of the fabrics' squared difference lies on "
            f"{100 * compared[model]['fabric_half_px']:.1f} % of the pixels the shell fills."
            if model in compared
            else ""
        ),
        "",
    ]


def _panels_markdown(doc: dict[str, Any]) -> list[str]:
    """Each panel's scene and numbers."""
    return [
        "## Each panel",
        "",
        results_files.markdown_table(
            [
                "Panel",
                "Size",
                "Fabric",
                "Day",
                "Frame",
                "t [s]",
                "finger [mm]",
                "normal [N]",
                "shear [N]",
                "max |difference| [DN]",
                "RMS [DN]",
                "smoothed: RMS [DN]",
            ],
            [
                [
                    "fabrics" if p["block"] == "fabric" else "days",
                    _size(p["size"]),
                    f"{p['fabric']} {p['name']}",
                    p["day"],
                    p["frame"],
                    f"{p['t_s']:.3f}",
                    f"{p['finger_mm']:.2f}",
                    f"{p['normal_n']:.3f}",
                    f"{p['shear_n']:+.3f}",
                    f"{p['max_abs_dn']:.2f}",
                    f"{p['rms_dn']:.2f}",
                    f"{p['smoothed_rms_dn']:.3f}",
                ]
                for p in doc["panels"]
            ],
        ),
    ]


def _noise_markdown(doc: dict[str, Any]) -> list[str]:
    """The camera's shot noise the figure leaves out, and the pixels where the reference lies below 0 DN."""
    return [
        "## The noise the figure leaves out",
        "",
        f"The camera's shot noise (`minsight._noise_sigma`) on {_name(doc['day_fabric'])}'s day-1 no-contact "
        "frame, over the pixels the shell fills: per pixel and channel of one frame, and of what a panel "
        "shows were the frames recorded (the channels' mean, one frame minus a reference averaged over "
        f"{archive.REFERENCE_FRAMES} frames).",
        "",
        results_files.markdown_table(
            ["Size", "Per channel: median [DN]", "Per channel: max [DN]", "Panel: median [DN]"],
            [
                [size, f"{n['channel_median_dn']:.2f}", f"{n['channel_max_dn']:.2f}", f"{n['panel_median_dn']:.2f}"]
                for size, n in doc["noise"].items()
            ],
        ),
    ] + _below_zero_markdown(doc)


def _below_zero_markdown(doc: dict[str, Any]) -> list[str]:
    below = {size: n for size, n in doc["noise"].items() if n["reference_below_zero_px"]}
    if below:
        return [
            "Where the no-contact frame lies below 0 DN, which light cannot, every panel of that day differs "
            "from 0 without any contact, and those pixels show as isolated dots: "
            + "; ".join(
                f"{n['reference_below_zero_px']} pixels at {size} (least {n['reference_min_dn']:.1f} DN)"
                for size, n in below.items()
            )
            + f" ({_name(doc['day_fabric'])}'s day 1).",
        ]
    return []
