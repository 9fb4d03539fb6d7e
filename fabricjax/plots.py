"""Figures people would rather look at than read: confusion matrices, latent t-SNE, Pareto fronts, PSDs.

Every function takes plain arrays, writes one PNG atomically and returns its path; no global
pyplot state survives a call (figures are created and closed here, Agg backend).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fabricjax import catalog  # noqa: E402
from fabricjax.atomic import atomic_open  # noqa: E402


def _save(fig, path) -> Path:
    try:
        with atomic_open(path) as f:
            fig.savefig(f, format="png", dpi=130, bbox_inches="tight")
    finally:
        plt.close(fig)
    return Path(path)


def confusion_matrix(labels, predictions, n_classes: int) -> np.ndarray:
    cm = np.zeros((n_classes, n_classes), np.int64)
    np.add.at(cm, (np.asarray(labels), np.asarray(predictions)), 1)
    return cm


def class_label(class_id: int) -> str:
    """'<id> <fabric name>' without the name's parenthesis, short enough for an axis tick."""
    return f"{class_id} {catalog.fabric(class_id).name.split(' (')[0]}"


def plot_confusions(path, panels: Sequence[tuple[str, np.ndarray, np.ndarray]], n_classes: int = catalog.N_CLASSES) -> Path:
    """One row-normalised confusion matrix per (title, labels, predictions) panel, side by side.

    Classes are labelled with the catalog's fabric names; the colour scale runs from 0 to the
    largest cell of any panel (shared, so panels compare), since near-chance models peak far
    below 1 and a fixed 0-1 scale would leave them white."""
    norms, titles = [], []
    for title, y, p in panels:
        cm = confusion_matrix(y, p, n_classes).astype(float)
        rows = cm.sum(1, keepdims=True)
        norms.append(np.divide(cm, rows, out=np.zeros_like(cm), where=rows > 0))
        titles.append(f"{title}\n{100.0 * np.trace(cm) / max(cm.sum(), 1):.1f}% correct of {int(cm.sum())}")
    vmax = max(max(float(n.max()) for n in norms), 1e-9)
    labels = [class_label(i) for i in range(n_classes)]
    fig, axes = plt.subplots(1, len(panels), figsize=(7.4 * len(panels), 7.0), squeeze=False, layout="constrained")
    for ax, norm, title in zip(axes[0], norms, titles):
        im = ax.imshow(norm, vmin=0, vmax=vmax, cmap="Blues")
        ax.set_title(title, fontsize=11)
        ax.set_xlabel("predicted class", fontsize=10)
        ax.set_ylabel("true class", fontsize=10)
        ax.set_xticks(range(n_classes), labels, rotation=90, fontsize=8)
        ax.set_yticks(range(n_classes), labels, fontsize=8)
    fig.colorbar(im, ax=axes[0].tolist(), fraction=0.03, label="fraction of the true class")
    return _save(fig, path)


_ROUGH_MARKERS = ("o", "s", "^", "D", "P")


def plot_latents(path, xy: np.ndarray, fabric_ids: Sequence[int], title: str = "t-SNE of per-trial mean latents") -> Path:
    """Training fabrics filled, new fabrics 21-23 outlined in black; colour = stretchiness,
    marker = roughness level, size = thickness level (the paper's Fig. latent_features)."""
    fig, ax = plt.subplots(figsize=(7.5, 6))
    colours = {0: "tab:blue", 1: "tab:orange", None: "grey"}
    for (x, y), fid in zip(np.asarray(xy), fabric_ids):
        f = catalog.fabric(int(fid))
        new = fid in catalog.NEW_FABRICS
        ax.scatter(
            x,
            y,
            s=40 + 45 * (f.thickness or 0),
            marker=_ROUGH_MARKERS[f.roughness or 0],
            c=colours[f.stretchiness],
            edgecolors="black" if new else "none",
            linewidths=2.0 if new else 0,
            alpha=0.85,
        )
        ax.annotate(str(fid), (x, y), fontsize=7, xytext=(3, 3), textcoords="offset points")
    handles = [plt.Line2D([], [], ls="", marker="o", color=colours[k], label=f"stretchiness {k}") for k in (0, 1)]
    handles += [plt.Line2D([], [], ls="", marker=m, color="grey", label=f"roughness {i}") for i, m in enumerate(_ROUGH_MARKERS)]
    handles += [plt.Line2D([], [], ls="", marker="o", mfc="white", mec="black", mew=2, label="new fabric (21-23)")]
    ax.legend(handles=handles, fontsize=7, loc="best", title="marker size = thickness", title_fontsize=7)
    ax.set(title=title, xlabel="t-SNE 1", ylabel="t-SNE 2")
    return _save(fig, path)


def plot_pareto(path, points: Sequence[dict], x_keys: Sequence[tuple[str, str]], highlight: str | None = None) -> Path:
    """Accuracy (mean ± SD) against each cost in `x_keys` [(key, axis label with unit)]; the
    Pareto front (no point both cheaper and more accurate) is drawn, `highlight` is marked."""
    fig, axes = plt.subplots(1, len(x_keys), figsize=(6.2 * len(x_keys), 4.8), squeeze=False)
    for ax, (key, label) in zip(axes[0], x_keys):
        xs = np.array([p[key] for p in points], float)
        ys = np.array([p["accuracy_mean"] for p in points], float)
        es = np.array([p.get("accuracy_sd", 0.0) for p in points], float)
        ax.errorbar(xs, ys, yerr=es, fmt="o", color="tab:blue", ecolor="lightgrey", capsize=2)
        order = np.lexsort((-ys, xs))
        front, best = [], -np.inf
        for i in order:
            if ys[i] > best:
                front.append(i)
                best = ys[i]
        ax.step(xs[front], ys[front], where="post", color="tab:red", lw=1, label="Pareto front")
        for p, x, y in zip(points, xs, ys):
            mark = p["name"] == highlight
            ax.annotate(
                p["name"] + (" (paper config)" if mark else ""),
                (x, y),
                fontsize=6.5,
                xytext=(4, -8 if mark else 3),
                textcoords="offset points",
                color="tab:red" if mark else "black",
                weight="bold" if mark else "normal",
            )
            if mark:
                ax.scatter([x], [y], s=160, facecolors="none", edgecolors="tab:red", linewidths=1.5)
        ax.set(xlabel=label, ylabel="test accuracy [%]")
        ax.margins(x=0.18, y=0.08)
        if np.all(xs > 0) and xs.max() / xs.min() > 20:
            ax.set_xscale("log")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return _save(fig, path)


def plot_psds(path, freqs_hz: np.ndarray, psds: dict[str, np.ndarray], noise: np.ndarray | None = None) -> Path:
    """Mean internal-microphone PSD per class, with the cafe noise in black (the paper's Fig. psds)."""
    fig, ax = plt.subplots(figsize=(8, 5))
    cmap = plt.get_cmap("turbo")
    for i, (name, p) in enumerate(psds.items()):
        ax.semilogy(freqs_hz / 1e3, p, lw=0.9, color=cmap(i / max(len(psds) - 1, 1)), label=name)
    if noise is not None:
        ax.semilogy(freqs_hz / 1e3, noise, lw=1.8, color="black", label="cafe noise")
    ax.set(xlabel="frequency [kHz]", ylabel="power spectral density [FS²/Hz]", title="Mean Minsound PSD per class")
    ax.legend(fontsize=6, ncol=3)
    ax.grid(alpha=0.3, which="both")
    return _save(fig, path)
