"""Deciding on the robot: calibrated confidence, when to stop rubbing, unknown fabrics.

    python -m experiments.decide --checkpoint=DIR[,DIR...]   # any train_and_evaluate checkpoints
    python -m experiments.decide                             # the quick model `experiments.stream` uses

Per model (its seed with the best validation score; no training):

* Calibration: one temperature per seed fitted on the validation split (`confidence.fit_temperature`),
  written beside the checkpoint (`confidence.TEMPERATURE_FILE`) so that the stream, the viewer
  and the decision rule apply it; the expected calibration error and reliability diagram on the
  test and cafe splits before and after it (the argmax, so the accuracy, is unchanged). Each
  split's accuracy stands beside its majority class (`findings.majority`), with a collapse flag
  where the model answers one class for nearly every sequence (`findings.collapsed`).
* When to stop rubbing: each trial's non-overlapping windows (its sequences, in order) feed the
  sequential rule (`confidence.sequential`): decide when the best class's posterior reaches a
  threshold, or at the trial's last window. Accuracy against mean touch time to the decision,
  one point per threshold of `THRESHOLDS`, beside the cost study's fixed-N points (its
  results/cost.json, where the results folder has one) and the majority class of the trials.
* Unknown fabrics: per test-day sequence, two scores of "not a trained class": 1 - the maximum
  calibrated probability, and the Mahalanobis distance of the model's pooled latents to the
  nearest training class (`confidence.Mahalanobis`, fitted on the training split). The unknowns
  are the test-day trials of the fabrics no training day has: on the simulated data the new
  fabrics 21-23 and the model's own excluded fabrics, on recorded data the model's excluded
  fabrics and `unknown_labels` (fabric ids, as `Config.exclude_fabrics`). AUROC and the
  false-accept rate at `confidence.KNOWN_RECALL` recall of known fabrics. With the Mahalanobis
  threshold fitted at that recall on the validation split, the decision rule answers "unknown"
  for a trial whose windows' mean score exceeds it; the share of known and unknown trials
  answered so is reported at `confidence.DECISION_THRESHOLD`.
"""

from __future__ import annotations

import dataclasses
import json
from typing import Any, Mapping, Sequence

import jax
import numpy as np
from flax import nnx

from fabricjax import catalog
from fabricjax.inference import confidence
from fabricjax.reporting import plots, results_files
from fabricjax.sequences import data
from fabricjax.store import archive, atomic, workspace
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import documents, findings, inference_cost, loading
from fabricjax.studies.machinery.quick_model import quick_model
from fabricjax.training import checkpoint, train

TITLE, PAPER = "Deciding on the robot", "not in the paper"
THRESHOLDS = (0.5, 0.7, 0.8, 0.9, 0.95, 0.99, 0.999, 0.9999)  # posterior thresholds of the sequential rule
EVAL_SPLITS = ("test", "cafe")
BATCH = 64  # sequences per forward pass


def encoder(graphdef):
    """`run(params, inputs)`: (fabric logits, pooled latents) of a batch, jitted once per model."""

    def run(params, x):
        model = nnx.merge(graphdef, params)
        return model(x)["fabric"], model.latents(x).mean(axis=1)

    return jax.jit(run)


def outputs(run, params, ss: data.SequenceSet, modalities) -> tuple[np.ndarray, np.ndarray]:
    """(fabric logits (N, classes), pooled latents (N, D)) of every sequence of `ss` by `run`
    (`encoder`), in batches of `BATCH` (the last one padded, so one compiled shape serves all)."""
    logits, latents = [], []
    for i in range(0, len(ss), BATCH):
        n = min(BATCH, len(ss) - i)
        x = {
            m: np.concatenate([ss.inputs[m][i : i + n], np.repeat(ss.inputs[m][i : i + 1], BATCH - n, axis=0)])
            for m in modalities
        }
        lo, la = run(params, x)
        logits.append(np.asarray(lo, np.float64)[:n])
        latents.append(np.asarray(la, np.float64)[:n])
    return np.concatenate(logits), np.concatenate(latents)


def trials(ss: data.SequenceSet) -> list[np.ndarray]:
    """Per trial of `ss` (in order of first appearance), its sequences' indices in time order."""
    keys = ss.info["trial_key"]
    order = dict.fromkeys(keys.tolist())
    return [np.flatnonzero(keys == k)[np.argsort(ss.info["start"][keys == k], kind="stable")] for k in order]


def unknown_fabrics(config, recorded: bool, unknown_labels: Sequence[int] | None) -> tuple[int, ...]:
    """The fabrics whose test-day trials are the unknowns (module docstring)."""
    base = set(config.exclude_fabrics) | set(unknown_labels or ())
    return tuple(sorted(base if recorded else base | set(catalog.NEW_FABRICS)))


def _calibration(probs: dict[str, np.ndarray], labels: np.ndarray) -> dict[str, Any]:
    return {
        k: {"ece": confidence.ece(p, labels), "reliability": confidence.reliability(p, labels)}
        for k, p in probs.items()
    }


def _restore_and_load(checkpoint_dir, unknown_labels, where: Location):
    """The checkpoint restored (refused without a fabric head or on other data), its best seed's
    index and the splits it is evaluated on, the unknown fabrics left out of training's classes."""
    restored = train.restore(checkpoint_dir)
    state, config = restored.state, restored.config
    checkpoint.require(
        checkpoint_dir,
        restored.trained_for,
        "the decision study",
        "a model with a fabric head",
        "fabric" in restored.trained_for["heads"],
    )
    index = int(np.argmax(np.asarray(state.best_val, np.float64)))
    unknown = unknown_fabrics(config, bool(where.data_dir), unknown_labels)
    data_config = dataclasses.replace(config, exclude_fabrics=unknown)
    ds = loading.load_dataset(
        data_config,
        data_dir=where.data_dir,
        workdir=where.workdir,
        split_names=("train", "val", *EVAL_SPLITS, "holdout"),
    )
    checkpoint.require_data(checkpoint_dir, restored.dataset, ds.sets["test"].dataset)
    sets = {k: v for k, v in ds.sets.items() if len(v)}
    for need in ("train", "val", "test"):
        if need not in sets:
            raise archive.ArchiveError(
                ds.folder, "<folder>", f"no {need}-split trials: the decision study needs train, val and test"
            )
    return restored, index, ds, sets


def evaluate_model(checkpoint_dir, *, unknown_labels=None, where: Location = Location()) -> dict[str, Any]:
    """One model's calibration, decision curves and unknown scores (module docstring); writes its
    temperatures beside the checkpoint."""
    restored, index, ds, sets = _restore_and_load(checkpoint_dir, unknown_labels, where)
    graphdef, state, config, seeds = restored.graphdef, restored.state, restored.config, restored.seeds
    encode = encoder(graphdef)
    temperatures = {}
    for i, s in enumerate(seeds):
        logits, _ = outputs(encode, checkpoint.select_seed(state.best_params, i), sets["val"], config.modalities)
        temperatures[s] = confidence.fit_temperature(logits, sets["val"].labels["fabric"])
    confidence.save_temperatures(checkpoint_dir, temperatures, "val")
    seed, t = seeds[index], temperatures[seeds[index]]
    params = checkpoint.select_seed(state.best_params, index)
    out = {name: outputs(encode, params, ss, config.modalities) for name, ss in sets.items()}
    mahalanobis = confidence.Mahalanobis.fit(out["train"][1], sets["train"].labels["fabric"])
    known_val = mahalanobis.score(out["val"][1])
    _, reject_above = confidence.false_accept_rate(known_val, known_val)
    window_s = config.seq_len / inference_cost.steps_and_rate(ds.folder, where.workdir)[1]

    splits_doc = {split: _split_doc(sets[split], out[split][0], t, window_s) for split in EVAL_SPLITS if split in sets}
    unknown_doc = _unknown_doc(sets, out, t, mahalanobis, reject_above) if "holdout" in sets else None
    return {
        "checkpoint": workspace.shown(checkpoint_dir),
        "config": config.to_json(),
        "seeds": list(seeds),
        "seed": seed,
        "temperatures": {str(s): v for s, v in temperatures.items()},
        "temperature": t,
        "window_s": window_s,
        "splits": splits_doc,
        "unknown": unknown_doc,
        "dataset": documents.dataset_doc(ds),
        "cost_points": _cost_points(where.results_dir(), config.modalities),
    }


def _split_doc(ss: data.SequenceSet, logits: np.ndarray, t: float, window_s: float) -> dict[str, Any]:
    """One evaluated split: accuracy, baselines, calibration before and after the temperature `t`,
    and the decision curves over its trials (`window_s`: the seconds a sequence spans)."""
    labels = ss.labels["fabric"]
    raw, cal = confidence.calibrated(logits), confidence.calibrated(logits, t)
    groups = trials(ss)
    tl = [int(labels[g[0]]) for g in groups]
    predicted = np.argmax(cal, -1)
    return {
        "sequences": len(labels),
        "trials": len(groups),
        "accuracy": float(np.mean(predicted == labels)),
        "majority": findings.majority(labels),
        "collapsed": findings.collapsed(predicted, labels)[0],
        "majority_trials": findings.majority(tl),
        "calibration": _calibration({"before": raw, "after": cal}, labels),
        "curve": confidence.decision_curve([cal[g] for g in groups], tl, THRESHOLDS, None, window_s),
        "curve_uncalibrated": confidence.decision_curve([raw[g] for g in groups], tl, THRESHOLDS, None, window_s),
    }


def _unknown_doc(sets, out, t: float, mahalanobis, reject_above: float) -> dict[str, Any]:
    """The held-out fabrics against the known test split: each unknown score's AUROC and false
    accepts, and the answers of the decision rule that rejects above `reject_above`."""
    known_cal = confidence.calibrated(out["test"][0], t)
    unk_cal = confidence.calibrated(out["holdout"][0], t)
    scores = {
        "max_probability": (1 - known_cal.max(-1), 1 - unk_cal.max(-1)),
        "mahalanobis": (mahalanobis.score(out["test"][1]), mahalanobis.score(out["holdout"][1])),
    }
    unknown_doc = {
        "fabrics": sorted(set(sets["holdout"].info["fabric_id"].tolist())),
        "known_sequences": len(known_cal),
        "unknown_sequences": len(unk_cal),
        "scores": {},
    }
    for name, (k, u) in scores.items():
        far, _ = confidence.false_accept_rate(k, u)
        unknown_doc["scores"][name] = {
            "auroc": confidence.auroc(k, u),
            "false_accept_at_recall": far,
            "known": np.asarray(k).tolist(),
            "unknown": np.asarray(u).tolist(),
        }
    unknown_doc["decision"] = {
        "threshold": confidence.DECISION_THRESHOLD,
        "reject_above": reject_above,
        "known": _answers(sets["test"], known_cal, scores["mahalanobis"][0], reject_above),
        "unknown": _answers(sets["holdout"], unk_cal, scores["mahalanobis"][1], reject_above),
    }
    return unknown_doc


def _answers(ss: data.SequenceSet, probs: np.ndarray, scores: np.ndarray, reject_above: float) -> dict[str, Any]:
    """The sequential rule at `confidence.DECISION_THRESHOLD` with "unknown" answers over `ss`'s trials:
    shares of trials answered unknown and answered with their own class."""
    unknown, right = [], []
    for g in trials(ss):
        d = confidence.sequential(probs[g], confidence.DECISION_THRESHOLD)
        is_unknown = bool(scores[g[: d.windows]].mean() > reject_above)
        unknown.append(is_unknown)
        right.append(not is_unknown and d.label == int(ss.labels["fabric"][g[0]]))
    return {
        "trials": len(unknown),
        "answered_unknown": float(np.mean(unknown)),
        "answered_own_class": float(np.mean(right)),
    }


def _cost_points(results, modalities) -> list[dict[str, float]] | None:
    """The cost study's fixed-N points of the same inputs (touch time, mean accuracy), None without
    its results/cost.json."""
    path = results_files.results_path(results) / "cost.json"
    if not path.exists():
        return None
    doc = json.loads(path.read_text())
    return [
        {"touch_s": p["touch_s"], "accuracy": p["accuracy_mean"] / 100, "name": p["name"]}
        for p in doc.get("points", [])
        if list(p["modalities"]) == list(modalities)
    ]


def run(
    checkpoint_dirs: Sequence = (),
    *,
    names: Sequence[str] | None = None,
    unknown_labels=None,
    preset: str = "default",
    overrides=None,
    where: Location = Location(),
) -> dict[str, Any]:
    """Evaluate every checkpoint (named by `names`, default by inputs; none given: the quick model
    of `preset` with `overrides`, as `experiments.stream`) and write results/decide.{md,json,png}."""
    if not checkpoint_dirs:
        checkpoint_dirs = [quick_model(preset, overrides, workdir=where.workdir, data_dir=where.data_dir)[3]]
    models = []
    for i, d in enumerate(checkpoint_dirs):
        m = evaluate_model(d, unknown_labels=unknown_labels, where=where)
        m["name"] = (
            names[i] if names else data.inputs_name(m["config"]["modalities"], documents.stream_names(m))
        )  # as tables name them
        models.append(m)
    with atomic.together():  # the figure, Markdown and JSON of this run, or none of them
        png = plots.plot_decide(where.results_dir() / "decide.png", models)
        doc = {
            **documents.header("decide", module=__name__, command=where.command, preset=models[0]["config"]["preset"]),
            "dataset": models[0].pop("dataset"),
            "thresholds": list(THRESHOLDS),
            "models": models,
        }
        for m in models[1:]:
            m.pop("dataset")
        return results_files.write(where.results_dir(), doc, markdown, [png])


def _pct(x) -> str:
    return "–" if x is None else f"{100 * x:.1f}"


def markdown(doc: dict[str, Any]) -> str:
    """The page: per model its calibration, when to stop rubbing, the cost study's points and the
    unknown fabrics; then the figure."""
    lines = [documents.title(doc, TITLE), "", documents.header_markdown(doc).rstrip("\n"), ""]
    for m in doc["models"]:
        lines += _calibration_markdown(doc, m) + _stopping_markdown(m) + _cost_markdown(m) + _unknown_markdown(m)
    lines += ["![calibration, touch time and unknown scores](decide.png)", ""]
    return "\n".join(lines)


def _calibration_markdown(doc: dict[str, Any], m: Mapping[str, Any]) -> list[str]:
    """A model's heading, checkpoint and temperature, and each split's calibration."""
    names = data.inputs_name(m["config"]["modalities"], documents.stream_names(doc))
    lines = [
        f"## {m['name']}" + ("" if names == m["name"] else f" ({names})"),
        "",
        f"- checkpoint: `{m['checkpoint']}`, seed {m['seed']} (best by validation of {m['seeds']}); "
        f"temperature {m['temperature']:.3f} (fitted on the validation split; written beside the checkpoint)",
        f"- one window: {m['window_s']:.2f} s of touch",
        "",
        "### Calibration",
        "",
    ]
    rows = [
        [
            s,
            d["sequences"],
            _pct(d["accuracy"]) + findings.collapse_text([d["collapsed"]]),
            findings.majority_cell(d["majority"]),
            _pct(d["calibration"]["before"]["ece"]),
            _pct(d["calibration"]["after"]["ece"]),
        ]
        for s, d in m["splits"].items()
    ]
    return lines + [
        results_files.markdown_table(
            ["split", "sequences", "accuracy [%]", "majority class [%]", "ECE before [%]", "ECE after [%]"], rows
        ),
        findings.baseline_note(),
        "",
    ]


def _stopping_markdown(m: Mapping[str, Any]) -> list[str]:
    """Each split's decision curve: accuracy and touch time per posterior threshold."""
    lines = ["### When to stop rubbing (sequential rule over a trial's windows)", ""]
    for s, d in m["splits"].items():
        rows = [
            [f"{c['threshold']:g}", _pct(c["accuracy"]), f"{c['mean_touch_s']:.2f}", _pct(c["confident"])]
            for c in d["curve"]
        ]
        lines += [
            f"{s} ({d['trials']} trials; majority class of the trials [%]: "
            f"{findings.majority_cell(d['majority_trials'])}):",
            "",
            results_files.markdown_table(
                ["threshold", "accuracy [%]", "mean touch to decision [s]", "reached the threshold [%]"], rows
            ),
            "",
        ]
    return lines


def _cost_markdown(m: Mapping[str, Any]) -> list[str]:
    """The cost study's fixed-N points of the model's inputs, where the results folder has them."""
    if m["cost_points"] is None:
        return [
            "The cost study's fixed-N points: no cost.json in this results folder (run `python -m experiments.cost`).",
            "",
        ]
    pts = (
        ", ".join(f"{p['touch_s']:.2f} s: {_pct(p['accuracy'])} %" for p in m["cost_points"]) or "none of these inputs"
    )
    return [f"The cost study's fixed-N points (test accuracy): {pts}.", ""]


def _unknown_markdown(m: Mapping[str, Any]) -> list[str]:
    """The unknown fabrics: each score's AUROC and false accepts, and the decision rule's answers."""
    u = m["unknown"]
    lines = ["### Unknown fabrics", ""]
    if u is None:
        return lines + ["No test-day trials of fabrics outside the training classes in the data: not evaluated.", ""]
    rows = [[k, f"{v['auroc']:.3f}", _pct(v["false_accept_at_recall"])] for k, v in u["scores"].items()]
    dd = u["decision"]
    return lines + [
        f"Unknowns: fabrics {', '.join(map(str, u['fabrics']))} ({u['unknown_sequences']} sequences) against "
        f"{u['known_sequences']} known test sequences.",
        "",
        results_files.markdown_table(
            ["score", "AUROC", f"false accepts at {100 * confidence.KNOWN_RECALL:.0f} % known recall [%]"], rows
        ),
        "",
        f'Decision rule at posterior {dd["threshold"]:g} answering "unknown" above the Mahalanobis '
        f"threshold of "
        f"{100 * confidence.KNOWN_RECALL:.0f} % validation recall: known trials "
        f"{_pct(dd['known']['answered_own_class'])} % "
        f"right, {_pct(dd['known']['answered_unknown'])} % called unknown; unknown trials "
        f"{_pct(dd['unknown']['answered_unknown'])} % called unknown.",
        "",
    ]
