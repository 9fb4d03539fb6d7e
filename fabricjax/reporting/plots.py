"""Figures people would rather look at than read: confusion matrices, latent t-SNE, Pareto fronts, PSDs.

Every function takes plain arrays, writes one PNG atomically and returns its path; no global
pyplot state survives a call (figures are created and closed here, Agg backend).
"""

from __future__ import annotations

from pathlib import Path
from typing import Collection, Mapping, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fabricjax import catalog, runtime  # noqa: E402
from fabricjax.store.atomic import atomic_open  # noqa: E402


def _save(fig, path) -> Path:
    """Written by process 0 only in a multi-process run (every process draws the same figure)."""
    try:
        if runtime.is_primary():
            with atomic_open(path, what="a figure") as f:
                fig.savefig(f, format="png", dpi=130, bbox_inches="tight")
    finally:
        plt.close(fig)
    return Path(path)


def class_label(class_id: int) -> str:
    """'<id> <fabric name>' without the name's parenthesis, short enough for an axis tick."""
    return f"{class_id} {catalog.fabric(class_id).name.split(' (')[0]}"


def plot_confusions(path, panels: Sequence[tuple[str, np.ndarray]], class_names: Sequence[str] | None = None) -> Path:
    """One row-normalised confusion matrix per (title, counts) panel (`stats.confusion_matrix`:
    true class by row, predicted by column), side by side.

    Classes are labelled with `class_names` (a dataset's own label map), else with the catalog's
    fabric names; the colour scale runs from 0 to the largest cell of any panel (shared, so panels
    compare), since near-chance models peak far below 1 and a fixed 0-1 scale would leave them white."""
    n_classes = len(panels[0][1])
    norms, titles = [], []
    for title, counts in panels:
        cm = np.asarray(counts, float)
        rows = cm.sum(1, keepdims=True)
        norms.append(np.divide(cm, rows, out=np.zeros_like(cm), where=rows > 0))
        titles.append(f"{title}\n{100.0 * np.trace(cm) / max(cm.sum(), 1):.1f}% correct of {int(cm.sum())}")
    vmax = max(max(float(n.max()) for n in norms), 1e-9)
    labels = [class_label(i) if class_names is None else f"{i} {class_names[i]}" for i in range(n_classes)]
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
_KEY_MARKER = "h"  # the keys of size and outline: not a roughness marker


def plot_latents(
    path,
    xy: np.ndarray,
    fabric_ids: Sequence[int],
    fabrics: Mapping[int, tuple[str, Mapping[str, int | None]]],
    holdouts: Collection[int],
    title: str = "t-SNE of latents, one point per fabric",
    neighbours: dict[int, int] | None = None,
) -> Path:
    """Colour = stretchiness, marker = roughness level, size = thickness level (the paper's Fig.
    latent_features), from `fabrics` (id -> name and property levels, None where unknown: the
    catalog's for the hand, the data's own for recorded data); `holdouts` (never trained on)
    outlined in black with bold numbers; `neighbours` (holdout id -> its nearest training fabric in
    latent space) drawn as dashed lines; every number named in a key beside the plot."""
    fig, ax = plt.subplots(figsize=(10.5, 6.4), layout="constrained")
    colours = {0: "tab:blue", 1: "tab:orange", None: "grey"}
    where = {int(f): (x, y) for (x, y), f in zip(np.asarray(xy), fabric_ids)}
    for h, t in (neighbours or {}).items():
        (x0, y0), (x1, y1) = where[h], where[t]
        ax.plot([x0, x1], [y0, y1], ls="--", lw=0.9, color="black", alpha=0.6, zorder=1)
    for fid, (x, y) in where.items():
        p = fabrics[fid][1]
        held = fid in holdouts
        ax.scatter(
            x,
            y,
            s=60 + 60 * (p["thickness"] or 0),
            marker=_ROUGH_MARKERS[p["roughness"] or 0],
            c=colours[p["stretchiness"]],
            edgecolors="black" if held else "none",
            linewidths=2.2 if held else 0,
            alpha=0.85,
            zorder=2,
        )
        ax.annotate(
            str(fid),
            (x, y),
            fontsize=9 if held else 8,
            weight="bold" if held else "normal",
            xytext=(5, 4),
            textcoords="offset points",
        )
    handles = [
        plt.Line2D([], [], ls="", marker="o", color=colours[k], label=f"stretchiness {('low', 'high')[k]}")
        for k in (0, 1)
    ]
    handles += [
        plt.Line2D(
            [],
            [],
            ls="",
            marker=m,
            color="grey",
            label=f"roughness {i} ({'very smooth' if i == 0 else 'very rough' if i == 4 else ''})".replace(" ()", ""),
        )
        for i, m in enumerate(_ROUGH_MARKERS)
    ]
    # size and outline apply to every marker: their keys use a shape that no roughness level has
    handles += [
        plt.Line2D([], [], ls="", marker=_KEY_MARKER, color="grey", ms=ms, label=f"thickness {t} (marker size)")
        for t, ms in zip(("thin", "medium", "thick"), (7, 10, 13))
    ]
    handles += [
        plt.Line2D(
            [], [], ls="", marker=_KEY_MARKER, mfc="white", mec="black", mew=2, label="holdout fabric (not trained on)"
        )
    ]
    if neighbours:
        handles += [
            plt.Line2D([], [], ls="--", color="black", label="holdout to nearest training fabric\n(in latent space)")
        ]
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    key = "\n".join(
        f"{'*' if fid in holdouts else ' '}{fid:>2} {fabrics[fid][0].split(' (')[0]}" for fid in sorted(where)
    )
    ax.text(1.01, 0.0, key + "\n* holdout", transform=ax.transAxes, fontsize=6.5, family="monospace", va="bottom")
    ax.set(title=title, xlabel="t-SNE 1", ylabel="t-SNE 2")
    ax.margins(0.08)
    return _save(fig, path)


_SPLIT_STYLE = {"val": ("validation", "tab:blue"), "test": ("lab test", "tab:red"), "cafe": ("cafe test", "tab:orange")}


def _seed_dots(ax, x: float, values: np.ndarray, colour: str, spread: float) -> None:
    """Every seed's value as a small dot, jittered sideways by a fixed pattern (no randomness)."""
    v = np.asarray(values, float)
    offsets = np.linspace(-spread, spread, v.size) if v.size > 1 else np.zeros(1)
    ax.scatter(x + offsets, v, s=12, color=colour, alpha=0.55, edgecolors="none", zorder=3)


def plot_against_bandwidth(
    path, khz: Sequence[float], series: dict[str, tuple[Sequence[np.ndarray], Sequence[float]]], microphone: str
) -> Path:
    """Accuracy [%] of `microphone` (the data's name for it) against PSD bandwidth: per split (`series`: split ->
    (per-seed values per
    bandwidth, the paper's mean per bandwidth or None: recorded data), every seed as a dot, our
    mean as a line, the paper's mean dashed."""
    fig, ax = plt.subplots(figsize=(8.8, 4.4), layout="constrained")
    x = np.asarray(khz, float)
    for i, (split, (per_seed, paper)) in enumerate(series.items()):
        name, colour = _SPLIT_STYLE[split]
        shift = (i - (len(series) - 1) / 2) * 0.35  # validation left, test right of each bandwidth
        for xi, v in zip(x, per_seed):
            _seed_dots(ax, xi + shift, v, colour, 0.12)
        ax.plot(
            x + shift,
            [np.mean(v) for v in per_seed],
            "o-",
            color=colour,
            lw=1.6,
            label=f"{name}, ours (mean; dots: seeds)",
        )
        if paper is not None:
            ax.plot(x, paper, "s--", color=colour, lw=1.0, mfc="white", alpha=0.8, label=f"{name}, paper (mean)")
    ax.set(xlabel="PSD bandwidth [kHz]", ylabel="accuracy [%]", title=f"{microphone} accuracy against PSD bandwidth")
    ax.set_xticks(x, [f"{k:g}" for k in x])
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    return _save(fig, path)


def plot_seed_bars(
    path, groups: Sequence[str], series: dict[str, tuple[Sequence[np.ndarray], Sequence[float | None]]], title: str
) -> Path:
    """Grouped bars of mean accuracy [%] with every seed's value as a dot: per split (`series`:
    split -> (per-seed values per group, the paper's mean per group or None)); the paper's mean
    is a black bar-wide tick, named in the legend with its split ("cafe test, paper (mean)")."""
    fig, ax = plt.subplots(figsize=(1.9 * len(groups) + 4.4, 4.4), layout="constrained")
    width = 0.8 / len(series)
    for i, (split, (per_seed, paper)) in enumerate(series.items()):
        name, colour = _SPLIT_STYLE[split]
        xs = np.arange(len(groups)) + (i - (len(series) - 1) / 2) * width
        ax.bar(
            xs,
            [np.mean(v) for v in per_seed],
            width * 0.92,
            color=colour,
            alpha=0.35,
            label=f"{name}, ours (mean; dots: seeds)",
        )
        for x, v in zip(xs, per_seed):
            _seed_dots(ax, x, v, colour, width * 0.3)
        for x, p in zip(xs, paper):
            if p is not None:
                ax.hlines(p, x - width * 0.46, x + width * 0.46, color="black", lw=2, zorder=4)
        if any(p is not None for p in paper):
            ax.hlines([], 0, 0, color="black", lw=2, label=f"{name}, paper (mean)")
    ax.set_xticks(range(len(groups)), groups, fontsize=8)
    ax.set(ylabel="accuracy [%]", title=title, ylim=(0, 100))
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    return _save(fig, path)


def plot_time_to_accuracy(path, curves: Sequence[tuple[str, np.ndarray, np.ndarray]], title: str) -> Path:
    """Validation accuracy [%] against training seconds, one line per row (`curves`: label, each
    epoch's end in seconds since the row started training, compilation in the first, and its
    validation accuracy per seed (seeds, epochs), NaN for an epoch the run did not train): the
    mean over seeds as a line, each seed's best epoch as a dot (the model the row keeps). Rows
    share a 0-100 % scale; camera rows (labels naming a camera input) get their own panel, so
    that neither panel's lines crowd the other's."""
    camera = [c for c in curves if "Minsight" in c[0] or "optical flow" in c[0]]
    panels = [p for p in ([c for c in curves if c not in camera], camera) if p]
    fig, axes = plt.subplots(1, len(panels), figsize=(7.2 * len(panels), 5.0), squeeze=False, layout="constrained")
    colours = plt.get_cmap("tab20")(np.linspace(0, 1, 20))
    for ax, panel in zip(axes[0], panels):
        for i, (label, seconds, per_seed) in enumerate(panel):
            colour = colours[(2 * i) % 20]
            mean = 100 * np.nanmean(per_seed, axis=0)
            ax.plot(seconds, mean, "-", color=colour, lw=1.6, label=label)
            best = np.nanargmax(np.where(np.isnan(per_seed), -np.inf, per_seed), axis=1)
            ax.plot(seconds[best], 100 * per_seed[np.arange(len(best)), best], "o", color=colour, ms=3.5, alpha=0.8)
        ax.set(xlabel="training time [s] (the first epoch includes compiling)", ylabel="validation accuracy [%]")
        ax.set(ylim=(0, 100), xlim=(0, None))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(title + " (lines: mean over seeds; dots: each seed's best epoch, the model kept)", fontsize=10)
    return _save(fig, path)


def clipped_errors(means: np.ndarray, sds: np.ndarray, low: float = 0.0, high: float = 100.0) -> np.ndarray:
    """(2, n) error bar extents (below, above) of mean ± SD, clipped to the range [low, high] an
    accuracy can take."""
    return np.stack([np.minimum(sds, means - low), np.minimum(sds, high - means)]).clip(min=0.0)


def plot_pareto(path, points: Sequence[dict], x_keys: Sequence[tuple[str, str]], highlight: str | None = None) -> Path:
    """Accuracy (mean ± SD, the bars clipped to 0-100 %) against each cost in `x_keys` [(key, axis
    label with unit)]; the Pareto front (no point both cheaper and more accurate) is drawn,
    `highlight` is marked."""
    fig, axes = plt.subplots(1, len(x_keys), figsize=(6.2 * len(x_keys), 4.8), squeeze=False)
    for ax, (key, label) in zip(axes[0], x_keys):
        xs = np.array([p[key] for p in points], float)
        ys = np.array([p["accuracy_mean"] for p in points], float)
        es = np.array([p.get("accuracy_sd", 0.0) for p in points], float)
        ax.errorbar(xs, ys, yerr=clipped_errors(ys, es), fmt="o", color="tab:blue", ecolor="lightgrey", capsize=2)
        order = np.lexsort((-ys, xs))
        front, best = [], -np.inf
        for i in order:
            if ys[i] > best:
                front.append(i)
                best = ys[i]
        ax.step(xs[front], ys[front], where="post", color="tab:red", lw=1, label="Pareto front")
        ax.set(xlabel=label, ylabel="test accuracy [%]")
        ax.margins(x=0.18, y=0.08)
        if np.all(xs > 0) and xs.max() / xs.min() > 20:
            ax.set_xscale("log")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        marked = [i for i, p in enumerate(points) if p["name"] == highlight]
        for i in marked:  # the paper's point: ringed, its label centred below the ring
            ax.scatter([xs[i]], [ys[i]], s=160, facecolors="none", edgecolors="tab:red", linewidths=1.5)
            ax.annotate(
                points[i]["name"] + " (paper config)",
                (xs[i], ys[i]),
                fontsize=6.5,
                xytext=(0, -16),
                textcoords="offset points",
                ha="center",
                color="tab:red",
                weight="bold",
            )
        _labels_apart(ax, xs, ys, [p["name"] for p in points], fontsize=6.5, skip=set(marked))
    return _save(fig, path)


def _labels_apart(
    ax, xs: np.ndarray, ys: np.ndarray, texts: Sequence[str], fontsize: float, skip: Collection[int] = ()
) -> None:
    """Label each point to its upper right, moving a label down (with a thin leader line) until it
    overlaps no label placed before it, from the highest point down: points close together (one
    touch time, say) keep readable labels. Call after the axes' limits and scales are final."""
    fig = ax.figure
    fig.canvas.draw()
    px_per_pt = fig.dpi / 72
    height, step = fontsize * 1.3 * px_per_pt, fontsize * 0.35 * px_per_pt
    at = ax.transData.transform(np.column_stack([xs, ys]))
    placed: list[tuple[float, float, float]] = []  # (left, right, bottom) of each label, in pixels
    for i in np.argsort(-at[:, 1], kind="stable"):
        if i in skip:
            continue
        left, width = at[i, 0] + 4 * px_per_pt, len(texts[i]) * fontsize * 0.55 * px_per_pt
        bottom = at[i, 1] + 2 * px_per_pt
        while any(abs(bottom - b) < height and left < r and lo < left + width for lo, r, b in placed):
            bottom -= step
        placed.append((left, left + width, bottom))
        moved = at[i, 1] + 2 * px_per_pt - bottom > height / 2
        ax.annotate(
            texts[i],
            (xs[i], ys[i]),
            xytext=((left - at[i, 0]) / px_per_pt, (bottom - at[i, 1]) / px_per_pt),
            textcoords="offset points",
            fontsize=fontsize,
            va="bottom",
            arrowprops={"arrowstyle": "-", "lw": 0.4, "color": "grey", "shrinkA": 0, "shrinkB": 2} if moved else None,
        )


def plot_psds(path, freqs_hz: np.ndarray, psds: dict[str, np.ndarray], noise: np.ndarray | None = None) -> Path:
    """Mean internal-microphone PSD per class (`psds`: legend name -> PSD), with the cafe noise in
    black (the paper's Fig. psds)."""
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


def plot_decide(path, models: Sequence[Mapping]) -> Path:
    """Per model of the decision study (`fabricjax.studies.diagnostics.decide`), one row of three panels: the
    reliability diagram of its test split before and after temperature scaling (and of its cafe
    split after), accuracy against mean touch time to decision of the sequential rule (one point
    per posterior threshold, test and cafe, the cost study's fixed-N points beside them), and the
    ROC of telling unknown fabrics from known ones by each unknown score."""
    fig, axes = plt.subplots(len(models), 3, figsize=(15, 4.4 * len(models)), layout="constrained", squeeze=False)
    styles = {"test": "tab:blue", "cafe": "tab:orange"}
    for (rel, cur, roc), m in zip(axes, models):
        rel.plot([0, 1], [0, 1], color="grey", lw=0.8, ls=":")
        for split, d in m["splits"].items():
            for when, ls in (("before", "--"), ("after", "-")):
                if split == "cafe" and when == "before":
                    continue
                r = d["calibration"][when]["reliability"]
                pts = [(c, a) for c, a in zip(r["confidence"], r["accuracy"]) if c is not None]
                rel.plot(
                    *zip(*pts),
                    ls,
                    marker="o",
                    ms=3,
                    color=styles.get(split),
                    label=f"{split} {when} (ECE {100 * d['calibration'][when]['ece']:.1f} %)",
                )
        rel.set(
            xlabel="confidence (max probability)",
            ylabel="accuracy",
            title=f"{m['name']}: reliability, T = {m['temperature']:.2f}",
            xlim=(0, 1),
            ylim=(0, 1.02),
        )
        rel.legend(fontsize=8)
        for split, d in m["splits"].items():
            c = d["curve"]
            cur.plot(
                [x["mean_touch_s"] for x in c],
                [100 * x["accuracy"] for x in c],
                "-o",
                ms=4,
                color=styles.get(split),
                label=f"{split}: sequential rule",
            )
            for x in c[:: max(1, len(c) // 4)]:
                cur.annotate(
                    f"{x['threshold']:g}",
                    (x["mean_touch_s"], 100 * x["accuracy"]),
                    fontsize=7,
                    textcoords="offset points",
                    xytext=(3, -9),
                )
        if m.get("cost_points"):
            cur.plot(
                [p["touch_s"] for p in m["cost_points"]],
                [100 * p["accuracy"] for p in m["cost_points"]],
                "ks",
                ms=5,
                label="cost study: fixed N (test)",
            )
        cur.set(
            xlabel="mean touch time to decision [s]",
            ylabel="accuracy [%]",
            title="when to stop rubbing (labels: posterior threshold)",
        )
        cur.legend(fontsize=8)
        roc.plot([0, 1], [0, 1], color="grey", lw=0.8, ls=":")
        u = m.get("unknown")
        if u:
            for name, s in u["scores"].items():
                k, v = np.asarray(s["known"]), np.asarray(s["unknown"])
                cuts = np.unique(np.concatenate([k, v, [np.inf]]))[::-1]
                roc.plot(
                    [np.mean(k >= t) for t in cuts],
                    [np.mean(v >= t) for t in cuts],
                    label=f"{name.replace('_', ' ')} (AUROC {s['auroc']:.2f})",
                )
            roc.legend(fontsize=8)
            roc.set_title(f"unknown fabrics {', '.join(map(str, u['fabrics']))}")
        else:
            roc.set_title("unknown fabrics: none in the data")
        roc.set(xlabel="known sequences flagged", ylabel="unknown sequences flagged", xlim=(0, 1), ylim=(0, 1.02))
    return _save(fig, path)


def ranked_bars(
    path, factors: Sequence[str], panels: Sequence[tuple[str, Mapping[str, Sequence[float]]]], title: str
) -> Path:
    """One panel per response: its factors' mu* as horizontal bars, largest on top, with the
    bootstrap interval as an error bar (`panels`: (response, SALib's Morris result)); two panels a
    row, text at 10-12 pt, so that a page of many responses stays readable."""
    cols = 2
    rows = -(-len(panels) // cols)
    fig, axes = plt.subplots(
        rows, cols, figsize=(7.0 * cols, 0.42 * len(factors) * rows + 1.4 * rows), layout="constrained", squeeze=False
    )
    for ax, (name, result) in zip(axes.flat, panels):
        mu, conf = np.asarray(result["mu_star"]), np.asarray(result["mu_star_conf"])
        order = np.argsort(mu)
        ax.barh(range(len(factors)), mu[order], xerr=conf[order], color="tab:blue", alpha=0.7, error_kw={"lw": 0.8})
        ax.set_yticks(range(len(factors)), [factors[i] for i in order], fontsize=10)
        ax.set_title(name, fontsize=11)
        ax.set_xlim(0, max(1.0, float((mu + conf).max()) * 1.05))
        ax.tick_params(axis="x", labelsize=10)
        ax.grid(alpha=0.3, axis="x")
    for ax in list(axes.flat)[len(panels) :]:
        ax.axis("off")
    fig.suptitle(title, fontsize=13)
    return _save(fig, path)


def plot_difference_panels(
    path,
    rows: Sequence[Sequence[tuple[str, np.ndarray]]],
    row_labels: Sequence[str],
    vmax: float,
    linear: float,
    label: str,
    title: str,
    width_in: float = 7.7,
) -> Path:
    """Images of signed values in a grid, one row of panels per entry of `rows` (each a list of
    (title, (h, w) image)), on one diverging colour scale shared by every panel, white at 0: linear
    within +-`linear` and logarithmic beyond it up to +-`vmax`, so that differences a few times
    `linear` stay visible beside ones a hundred times larger. `row_labels` name each row at its
    left. The figure is `width_in` inches wide (1000 px at the saved 130 dpi), so that its titles
    stay legible at page width. Pixels are drawn as squares without smoothing, so a small image
    shows its own pixels."""
    from matplotlib.colors import SymLogNorm

    cols = max(len(r) for r in rows)
    panel_in = (width_in - 1.2) / cols
    h, w = rows[0][0][1].shape
    fig, axes = plt.subplots(
        len(rows),
        cols,
        figsize=(width_in, len(rows) * (panel_in * h / w + 0.45) + 0.6),
        layout="constrained",
        squeeze=False,
    )
    norm = SymLogNorm(linthresh=linear, linscale=1.0, vmin=-vmax, vmax=vmax, base=10)
    shown = None
    for r, panels in enumerate(rows):
        for c in range(cols):
            ax = axes[r, c]
            ax.set_xticks([])
            ax.set_yticks([])
            if c >= len(panels):
                ax.axis("off")
                continue
            name, image = panels[c]
            shown = ax.imshow(image, cmap="RdBu_r", norm=norm, interpolation="nearest")
            ax.set_title(name, fontsize=8)
            for side in ax.spines.values():
                side.set_visible(False)
        axes[r, 0].set_ylabel(row_labels[r], fontsize=8)
    if shown is not None:
        fig.colorbar(shown, ax=axes, shrink=0.8, label=label, extend="both", aspect=30)
    fig.suptitle(title, fontsize=9)
    return _save(fig, path)


def plot_soak(path, series: Sequence[tuple[str, Sequence[float]]], from_run: int, flat: float) -> Path:
    """Resident memory [MB] per run, one line per way of running (`series`: label, MB per run),
    with the band in which it must stay from run `from_run` on (within `flat` of that run's)."""
    fig, ax = plt.subplots(figsize=(7.2, 4.2), layout="constrained")
    for i, (label, mb) in enumerate(series):
        runs = np.arange(1, len(mb) + 1)
        colour = plt.get_cmap("tab10")(i)
        ax.plot(runs, mb, "o-", color=colour, ms=3, lw=1.2, label=label)
        if len(mb) >= from_run:
            ref = mb[from_run - 1]
            ax.fill_between([from_run, len(mb)], ref * (1 - flat), ref * (1 + flat), color=colour, alpha=0.12, lw=0)
    ax.set(xlabel="run", ylabel="resident memory [MB]", ylim=(0, None))
    ax.set_title(f"Resident memory per run (bands: within {100 * flat:.0f} % of run {from_run})", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    return _save(fig, path)
