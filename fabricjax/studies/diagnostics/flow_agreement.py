"""How closely the JAX Farneback (features/farneback.py) reproduces OpenCV's, and what it costs.

    python -m experiments.flow_agreement --results=results

`Config.flow_method="jax"` computes the flow feature in JAX instead of OpenCV; OpenCV stays the
default and the reference. Two kinds of frames, each at the paper's 308x410 and at 60x80:

  minsight  simulated Minsight frames (sim/minsight.py): a stretch of `STEPS` consecutive frames
            of a trial of each of `FABRICS`, where the fingertip's shear load changes fastest;
            rendered directly at each size, without simulating a dataset.
  natural   a natural-image-like texture (1/f amplitude spectrum, a lighting gradient with
            vignetting, sensor noise) moved by a smooth known motion field: frame k shows the
            texture displaced by k times the field, so each step moves by about the field.

Per set, over every frame pair: the end-point error (EPE) between the two methods' dense flow
(mean, median, p95, p99, max, in pixels) beside OpenCV's mean flow magnitude for scale; for the
natural frames also each method's mean EPE to the known motion; and the agreement of what the
model reads, the sparsified and pooled feature (`flow.sparsify_and_pool`, both readings):
relative L2 difference and correlation. Then seconds per frame pair (`timing.bench_flow`).
"""

from __future__ import annotations

import time
from typing import Any

import cv2
import numpy as np

from fabricjax import timing
from fabricjax.features import flow
from fabricjax.reporting import results_files
from fabricjax.sim import Scene, minsight, trial
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents

STUDY = "flow_agreement"
SIZES = ((308, 410), (60, 80))
FABRICS = (3, 11)  # one trial each (day 1, trial 0)
SEEDS = (0, 1)  # natural texture and motion field per seed
STEPS = 8  # frames per stretch (7 frame pairs): the timing's batch, so both use one compiled program per size
STREAMS = ("audio", "proprio", "images")
MOTION_PX = 1.5  # largest per-step displacement of the natural frames' field at 308x410 (scaled with the width)
NOISE_DN = 2.0  # sensor noise SD of the natural frames, in 8-bit levels
PERCENTILES = (50, 95, 99)


def minsight_frames(size: tuple[int, int], fabric_id: int, steps: int = STEPS) -> np.ndarray:
    """(steps, H, W, 3) uint8 simulated frames of one trial, where its shear changes fastest."""
    scene = Scene(fabric_id, streams=STREAMS, image_size=size)
    proc = trial.procedure(scene)
    shear = np.interp(proc.frame_times, proc.motion.t, proc.motion.shear_n)
    change = np.convolve(np.abs(np.diff(shear)), np.ones(steps - 1), "valid")
    start = int(np.argmax(change))
    return minsight.render(
        scene, proc.motion, proc.frame_times[start : start + steps], proc.nuisance, scene.rng("minsight", "trial")
    )


def _one_over_f(size: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    h, w = size
    f = np.hypot(*np.meshgrid(np.fft.fftfreq(h), np.fft.fftfreq(w), indexing="ij"))
    spectrum = (rng.standard_normal((h, w)) + 1j * rng.standard_normal((h, w))) / np.where(f > 0, f, np.inf)
    t = np.fft.ifft2(spectrum).real
    return (t - t.mean()) / t.std()


def natural_frames(size: tuple[int, int], seed: int, steps: int = STEPS) -> tuple[np.ndarray, np.ndarray]:
    """(steps, H, W, 3) uint8 frames and the (H, W, 2) motion field (x, y) each step moves by."""
    rng = np.random.default_rng(seed)
    h, w = size
    texture = _one_over_f(size, rng)
    y, x = np.mgrid[:h, :w].astype(np.float32)
    phase = rng.uniform(0, 2 * np.pi, 3)
    amp = MOTION_PX * w / SIZES[0][1]
    u = amp * (0.6 * np.sin(2 * np.pi * x / w + phase[0]) * np.cos(np.pi * y / h) + 0.4)
    v = amp * 0.6 * np.cos(2 * np.pi * y / h + phase[1]) * np.sin(np.pi * x / w + phase[2])
    u, v = u.astype(np.float32), v.astype(np.float32)
    light = (0.55 + 0.35 * x / w + 0.1 * y / h) * (1 - 0.3 * (((x - w / 2) / w) ** 2 + ((y - h / 2) / h) ** 2))
    frames = []
    for k in range(steps):
        moved = cv2.remap(
            texture.astype(np.float32), x - k * u, y - k * v, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT_101
        )
        img = 255 * light * (0.5 + 0.15 * moved) + rng.normal(0, NOISE_DN, size)
        frames.append(np.clip(np.rint(img), 0, 255).astype(np.uint8))
    gray = np.stack(frames)
    return np.repeat(gray[..., None], 3, axis=-1), np.stack([u, v], -1)


def _epe(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.hypot(a[..., 0] - b[..., 0], a[..., 1] - b[..., 1])


def compare(stretches: list[np.ndarray], truths: list[np.ndarray] | None = None) -> dict[str, Any]:
    """The module docstring's statistics over every frame pair of `stretches` (step 0 of each has
    no predecessor and is left out)."""
    dense = {m: [np.asarray(flow.farneback(s, method=m)) for s in stretches] for m in flow.METHODS}
    ours, ref = (np.concatenate([d[1:] for d in dense[m]]) for m in ("jax", "opencv"))
    epe = _epe(ours, ref)
    out = {
        "pairs": len(ours),
        "epe_mean": float(epe.mean()),
        **{f"epe_p{p}": float(np.percentile(epe, p)) for p in PERCENTILES},
        "epe_max": float(epe.max()),
        "opencv_magnitude_mean": float(np.hypot(ref[..., 0], ref[..., 1]).mean()),
    }
    if truths is not None:
        truth = np.concatenate([np.broadcast_to(t, (len(s) - 1, *t.shape)) for s, t in zip(stretches, truths)])
        out.update(
            opencv_truth_epe_mean=float(_epe(ref, truth).mean()), jax_truth_epe_mean=float(_epe(ours, truth).mean())
        )
    for mode in flow.SPARSIFY:
        a, b = (
            np.concatenate([np.asarray(flow.sparsify_and_pool(d, mode))[1:] for d in dense[m]]).ravel()
            for m in ("jax", "opencv")
        )
        out[mode] = {
            "relative_l2": float(np.linalg.norm(a - b) / np.linalg.norm(b)),
            "correlation": float(np.corrcoef(a, b)[0, 1]),
        }
    return out


def run(*, quick: bool = False, where: Location = Location()) -> dict[str, Any]:
    """Every set at every size, then the timing; writes results/flow_agreement.{md,json}. `quick`:
    one trial and one natural texture per size, timing best of one."""
    t0 = time.perf_counter()
    fabrics, seeds = (FABRICS[:1], SEEDS[:1]) if quick else (FABRICS, SEEDS)
    sets = []
    for size in SIZES:
        sets.append({"frames": "minsight", "size": list(size), **compare([minsight_frames(size, f) for f in fabrics])})
        natural = [natural_frames(size, s) for s in seeds]
        sets.append(
            {"frames": "natural", "size": list(size), **compare([f for f, _ in natural], [t for _, t in natural])}
        )
    speed = timing.bench_flow(SIZES, batch=STEPS, repeats=1 if quick else 3)
    doc = {
        **documents.header(
            STUDY,
            module=__name__,
            command=where.command,
            quick=quick,
            fabrics=list(fabrics),
            textures=list(seeds),
            steps=STEPS,
            wall_s=time.perf_counter() - t0,
        ),
        "sets": sets,
        "timing": speed,
    }
    return results_files.write(where.results_dir(), doc, markdown)


def markdown(doc: dict[str, Any]) -> str:
    """The page: the frames compared, the dense flow's errors, the model's input and the time per pair."""
    return "\n".join([*_intro_markdown(doc), *_dense_markdown(doc), *_input_markdown(doc), *_time_markdown(doc)]) + "\n"


def _intro_markdown(doc: dict[str, Any]) -> list[str]:
    """The title, where the numbers come from and the frames compared."""
    return [
        "# Farneback optical flow: the JAX reimplementation against OpenCV",
        "",
        documents.header_markdown(
            doc, f"{doc['wall_s']:.0f} s" + (" (--quick: one trial and one texture per size)" if doc["quick"] else "")
        ),
        "",
        f"Frames: simulated Minsight frames, {doc['steps']} consecutive frames of one trial of each of "
        f"fabrics {doc['fabrics']} where the "
        f"shear changes fastest; natural-like textures (seeds {doc['textures']}) moved by a smooth known "
        f"field. End-point errors (EPE) "
        "are in pixels, between the two methods' dense flow over every frame pair; features are "
        "`flow.sparsify_and_pool` of each.",
        "",
    ]


def _dense_markdown(doc: dict[str, Any]) -> list[str]:
    """The end-point errors between the two methods' dense flow, and each method's to the truth."""
    return [
        "## Dense flow",
        "",
        results_files.markdown_table(
            [
                "Frames",
                "Size",
                "Pairs",
                "EPE mean",
                "median",
                "p95",
                "p99",
                "max",
                "OpenCV |flow| mean",
                "EPE to truth (OpenCV / JAX)",
            ],
            [
                [
                    s["frames"],
                    f"{s['size'][0]}x{s['size'][1]}",
                    s["pairs"],
                    *(f"{s[k]:.2e}" for k in ("epe_mean", "epe_p50", "epe_p95", "epe_p99", "epe_max")),
                    f"{s['opencv_magnitude_mean']:.3f}",
                    f"{s['opencv_truth_epe_mean']:.4f} / {s['jax_truth_epe_mean']:.4f}"
                    if "jax_truth_epe_mean" in s
                    else "-",
                ]
                for s in doc["sets"]
            ],
        ),
        "",
    ]


def _input_markdown(doc: dict[str, Any]) -> list[str]:
    """How close the two methods' sparsified, pooled features are."""
    return [
        "## The model's input (sparsified, 3x3-pooled)",
        "",
        results_files.markdown_table(
            ["Frames", "Size", *(f"{m}: {k}" for m in flow.SPARSIFY for k in ("relative L2", "correlation"))],
            [
                [
                    s["frames"],
                    f"{s['size'][0]}x{s['size'][1]}",
                    *(
                        f"{s[m][k]:.2e}" if k == "relative_l2" else f"{s[m][k]:.6f}"
                        for m in flow.SPARSIFY
                        for k in ("relative_l2", "correlation")
                    ),
                ]
                for s in doc["sets"]
            ],
        ),
        "",
    ]


def _time_markdown(doc: dict[str, Any]) -> list[str]:
    """Each method's time per frame pair."""
    t = doc["timing"]
    return [
        "## Time per frame pair",
        "",
        f"OpenCV on one thread (cv2.setNumThreads(1), one pair at a time) and on {t['opencv_threads']} "
        f"threads (pairs in a thread pool); "
        f"JAX on {t['jax_devices']} {t['device'].upper()} device(s), batches of {t['batch']} pairs split "
        f"over them, after compilation.",
        "",
        results_files.markdown_table(
            [
                "Size",
                "OpenCV, 1 thread [ms]",
                f"OpenCV, {t['opencv_threads']} threads [ms]",
                "JAX [ms]",
                "JAX compile [s]",
            ],
            [
                [
                    size,
                    *(f"{1e3 * v[k]:.2f}" for k in ("opencv_1_thread_s", "opencv_all_cores_s", "jax_s")),
                    f"{v['jax_compile_s']:.1f}",
                ]
                for size, v in t["sizes"].items()
            ],
        ),
    ]
