"""Which of the simulator's estimates each finding depends on: a Morris screening over their declared ranges.

    python -m experiments.sensitivity                       # into workspace/results/
    python -m experiments.sensitivity --results=results     # regenerates results/sensitivity.{md,json,png}

The simulator's unknown magnitudes are declared in `sim.estimates`, each with a range a physical
reason allows. This study moves them within those ranges and measures what every probe-level
finding does: a Morris elementary-effects screening (SALib, `sample`/`analyze`), whose factors
are the registry's groups (the estimates of one group act on one mechanism and move together,
each to the same relative place in its own range, log-spaced where declared so). Each trajectory
starts at a random point of a `LEVELS`-level grid and moves one group at a time, so k groups and r
trajectories cost r (k + 1) points. At each point the reduced `sensitivity` preset (every fabric,
fewer and shorter trials: its data simulates in about a minute on 2 cores) is simulated with the
point's estimates in its own workspace, and measured:

* the linear probe (`probe`) of every single input and of the noise table's rows: validation
  (training days) and test (new day) accuracy, and the cafe accuracy;
* the fabric and day shares of every input's per-trial variation (`day_shift`);
* Minsound's and the palm microphone's lab-to-cafe drop (probe test minus cafe);
* a probe of the image (minus its session's reference) on the thickness and roughness labels.

Per response, each group's influence is mu* (the mean absolute elementary effect, in the
response's unit, over the trajectories) with its bootstrap 95 % interval and sigma (the spread of
its effects: interactions or non-linearity). The paper's claims a probe can speak to (`CLAIMS`)
are evaluated at every point: whether some point inside the declared ranges makes each hold, and
which groups move it most. Deterministic by `seed`; resumable (each point's measurements are kept
under <workspace>/sensitivity/; its data is removed once measured); a progress bar with the time
left after the first point.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import time
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np
from SALib.analyze import morris as morris_analyze
from SALib.sample import morris as morris_sample
from scipy import stats as sstats
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from fabricjax import presets
from fabricjax.config import Config
from fabricjax.errors import UserError
from fabricjax.reporting import plots, results_files
from fabricjax.sim import estimates
from fabricjax.store import atomic, provenance, workspace
from fabricjax.store.workspace import Location
from fabricjax.studies.machinery import day_variation, documents, loading, probing
from fabricjax.studies.machinery.linear_probe import BLAS_THREADS, fit, prepare_inputs

STUDY = "sensitivity"
PRESET = "sensitivity"
LEVELS = 4  # Morris grid levels per factor (SALib's default; p/2 levels apart per step)
TRAJECTORIES = 3  # r (k + 1) points: about an hour on 2 cores with every group
SINGLE = ("internal", "external", "proprio", "flow", probing.SESSION + "image")
PROBE_ROWS = (*SINGLE, "internal+proprio", "internal+external+proprio")
SHIFT_ROWS = SINGLE
PROPERTIES = ("thickness", "roughness")
ALPHA = 0.01  # a probe "carries" a label when its test accuracy beats its chance at this level (binomial, one-sided)
# "close": within the larger seed SD of the paper's two rows compared (flow 47.16 +- 5.12, proprioception 47.10 +- 3.72)
CLOSE_PP = 5.12


# A row's inputs by the paper's names, as the day shift names them (every single input is one of its rows).
_NAMES = {r.name: r.label for r in day_variation.ROWS}


class Response:
    """The responses' names, one definition for what `measure` records, the claims read and the plot shows."""

    MINSOUND_MARGIN = "Minsound margin over the best other single input [pp]"
    FLOW_OVER_IMAGE = "optical flow − image, test [pp]"
    PROPRIO_VS_FLOW = "proprioception − optical flow, test [pp]"
    PALM_CAFE_GAIN = "palm's gain in the cafe [pp]"
    IMAGE_PROPERTY_MARGIN = "image property margin over chance, test [pp]"
    BEST_CAMERA = "best camera input, test [%]"
    MINSOUND_CAFE_DROP = "Minsound lab → cafe drop [pp]"
    PALM_CAFE_DROP = "palm mic lab → cafe drop [pp]"

    @staticmethod
    def probe_validation(row: str) -> str:
        return f"probe validation: {_NAMES[row]} [%]"

    @staticmethod
    def probe_test(row: str) -> str:
        return f"probe test: {_NAMES[row]} [%]"

    @staticmethod
    def fabric_share(row: str) -> str:
        return f"fabric share: {_NAMES[row]} [%]"

    @staticmethod
    def day_share(row: str) -> str:
        return f"day share: {_NAMES[row]} [%]"


@dataclasses.dataclass(frozen=True)
class Claim:
    """A paper claim as a predicate over one point's responses; `response` is the number it reads."""

    text: str
    response: str
    holds: Callable[[Mapping[str, float], Mapping[str, Any]], bool]


def _above_chance(accuracy: float, n: int, chance: float) -> bool:
    return n > 0 and sstats.binomtest(int(round(accuracy * n)), n, chance, alternative="greater").pvalue < ALPHA


CLAIMS = (
    Claim(
        "Minsound is the best single input (probe, new day)",
        Response.MINSOUND_MARGIN,
        lambda r, _: r[Response.MINSOUND_MARGIN] > 0,
    ),
    Claim(
        "the image reads below optical flow (probe, new day)",
        Response.FLOW_OVER_IMAGE,
        lambda r, _: r[Response.FLOW_OVER_IMAGE] > 0,
    ),
    Claim(
        f"proprioception is close to optical flow (within {CLOSE_PP} pp, probe, new day)",
        Response.PROPRIO_VS_FLOW,
        lambda r, _: abs(r[Response.PROPRIO_VS_FLOW]) <= CLOSE_PP,
    ),
    Claim(
        "the palm microphone helps in the cafe (Minsound + proprioception + palm mic > Minsound + "
        "proprioception, probe)",
        Response.PALM_CAFE_GAIN,
        lambda r, _: r[Response.PALM_CAFE_GAIN] > 0,
    ),
    Claim(
        f"the camera carries thickness and roughness to a new day (image probe above chance, p < {ALPHA})",
        Response.IMAGE_PROPERTY_MARGIN,
        lambda r, s: all(s[f"image carries {p}"] for p in PROPERTIES),
    ),
    Claim(
        f"the image or optical flow carries the fabric to a new day (probe above chance, p < {ALPHA})",
        Response.BEST_CAMERA,
        lambda r, s: s["camera carries the fabric"],
    ),
)


def moved() -> list[estimates.Estimate]:
    """The estimates the study moves: all but the calibrated, which a measurement of the paper pins."""
    return [e for e in estimates.ESTIMATES.values() if e.calibrated is None]


def screened_groups() -> tuple[str, ...]:
    """The groups with an estimate to move, in the registry's order."""
    return tuple(dict.fromkeys(e.group for e in moved()))


def point_values(u: np.ndarray, groups: Sequence[str]) -> dict[str, float]:
    """The moved estimates' values at the point whose groups sit at relative places `u` of their ranges."""
    place = dict(zip(groups, u))
    return {e.name: e.at(float(place[e.group])) for e in moved() if e.group in place}


def _probe_rows(doc: Mapping[str, Any]) -> dict[str, Mapping[str, Any]]:
    return {r["name"]: r for r in doc["rows"]}


def _property_probe(point: Path, preset: str) -> dict[str, Any]:
    """The image (minus its session's reference) probed on each property's labels: test accuracy,
    the training split's majority share (its chance) and the test size."""
    config = Config.from_preset(preset, modalities=("image",), image_reference="session")
    splits = list(loading.TRAIN_VAL_TEST)
    ds = loading.load_dataset(config, workdir=point, split_names=splits)
    inputs = prepare_inputs(ds.sets, ["image"], splits)["image"].features
    out = {}
    with threadpool_limits(BLAS_THREADS):
        for p in PROPERTIES:
            keep = {s: ds.sets[s].labels[p] >= 0 for s in splits}
            labels = {s: ds.sets[s].labels[p][keep[s]] for s in splits}
            if len(np.unique(labels["train"])) < 2:
                raise UserError(f"the {preset} preset's training split has fewer than two {p} levels: nothing to probe")
            result = fit({s: inputs[s][keep[s]] for s in splits}, labels)
            chance = float(np.bincount(labels["train"]).max() / len(labels["train"]))
            out[p] = {"test": result["accuracy"]["test"], "chance": chance, "n": int(len(labels["test"]))}
    return out


def measure(point: Path, preset: str) -> tuple[dict[str, float], dict[str, Any]]:
    """Simulate `preset` with the estimates in force into the workspace `point` and measure every
    response; returns (responses, what the claims read besides them)."""
    where = Location(workdir=point, results=point / "results")
    probe_doc = probing.measure(preset=preset, rows=list(PROBE_ROWS), where=where).result.to_json()
    p = _probe_rows(probe_doc)
    shift = day_variation.measure(preset=preset, rows=list(SHIFT_ROWS), where=where)
    shares = {r["name"]: r for r in shift.body["rows"]}
    props = _property_probe(point, preset)
    acc = {name: {s: 100 * v for s, v in r["accuracy"].items()} for name, r in p.items()}
    out: dict[str, float] = {}
    for row in SINGLE:
        out[Response.probe_validation(row)] = acc[row]["val"]
        out[Response.probe_test(row)] = acc[row]["test"]
        out[Response.fabric_share(row)] = 100 * shares[row]["shares"]["fabric"]
        out[Response.day_share(row)] = 100 * shares[row]["shares"]["day"]
    out[Response.MINSOUND_CAFE_DROP] = acc["internal"]["test"] - acc["internal"]["cafe"]
    out[Response.PALM_CAFE_DROP] = acc["external"]["test"] - acc["external"]["cafe"]
    image = probing.SESSION + "image"
    out[Response.MINSOUND_MARGIN] = acc["internal"]["test"] - max(acc[r]["test"] for r in SINGLE if r != "internal")
    out[Response.FLOW_OVER_IMAGE] = acc["flow"]["test"] - acc[image]["test"]
    out[Response.PROPRIO_VS_FLOW] = acc["proprio"]["test"] - acc["flow"]["test"]
    out[Response.PALM_CAFE_GAIN] = acc["internal+external+proprio"]["cafe"] - acc["internal+proprio"]["cafe"]
    out[Response.IMAGE_PROPERTY_MARGIN] = min(100 * (props[q]["test"] - props[q]["chance"]) for q in PROPERTIES)
    out[Response.BEST_CAMERA] = max(acc["flow"]["test"], acc[image]["test"])
    n_test = probe_doc["dataset"]["sequences"]["test"]
    chance = 1 / len(probe_doc["classes"])
    side = {
        **{
            f"image carries {q}": _above_chance(props[q]["test"], props[q]["n"], props[q]["chance"]) for q in PROPERTIES
        },
        "camera carries the fabric": any(_above_chance(acc[r]["test"] / 100, n_test, chance) for r in ("flow", image)),
        "properties": props,
        "chance": chance,
    }
    return out, side


def design(groups: Sequence[str], trajectories: int, seed: int) -> np.ndarray:
    """The Morris sample: (trajectories (k + 1), k) relative places in [0, 1], one column per group."""
    problem = {"num_vars": len(groups), "names": list(groups), "bounds": [[0.0, 1.0]] * len(groups)}
    return morris_sample.sample(problem, trajectories, num_levels=LEVELS, seed=seed)


def analyse(groups: Sequence[str], x: np.ndarray, y: np.ndarray, seed: int) -> dict[str, list[float]]:
    problem = {"num_vars": len(groups), "names": list(groups), "bounds": [[0.0, 1.0]] * len(groups)}
    with np.errstate(all="ignore"):
        a = morris_analyze.analyze(problem, x, y, num_levels=LEVELS, seed=seed)
    return {k: [float(v) for v in a[k]] for k in ("mu", "mu_star", "sigma", "mu_star_conf")}


PUBLISHED = provenance.repository_root() / "results" / f"{STUDY}.json"


def prior_estimate(preset: str, n_points: int) -> str:
    """The time `n_points` points should take, from the repository's published run of the same
    preset (its median point; other machines differ), before this run has measured its first."""
    try:
        doc = json.loads(PUBLISHED.read_text())
        seconds = float(np.median([p["wall_s"] for p in doc["points"]]))
    except (OSError, ValueError, KeyError):
        return "The first point's time gives the estimate for the rest."
    if doc.get("preset") != preset:
        return "The first point's time gives the estimate for the rest."
    m = doc["machine"]
    return (
        f"Estimated {n_points * seconds / 60:.0f} min: the published run took {seconds:.0f} s a point on "
        f"{m['cpu']}, {m['cores']} cores "
        "(other machines differ); the first point's time refines it."
    )


def _points_folder(where: Location, preset: str, groups: Sequence[str], trajectories: int, seed: int, x) -> Path:
    """The folder that keeps the screening's points, emptied where it holds another registry's or
    design's (its points measure something else), with the plan its points are of."""
    folder = workspace.root(where.workdir) / "sensitivity" / f"{preset}-r{trajectories}-seed{seed}"
    plan = {
        "preset": preset,
        "groups": list(groups),
        "trajectories": trajectories,
        "seed": seed,
        "design": x.tolist(),
        "estimates": {e.name: dataclasses.asdict(e) for e in moved() if e.group in groups},
    }
    folder.mkdir(parents=True, exist_ok=True)
    plan_path = folder / "plan.json"
    if plan_path.is_file() and json.loads(plan_path.read_text()) != json.loads(json.dumps(plan)):
        shutil.rmtree(folder)  # another registry or design: its points measure something else
        folder.mkdir(parents=True)
    results_files.write_json(plan_path, plan)
    return folder


def _measure_points(folder: Path, x: np.ndarray, groups: Sequence[str], preset: str, progress: bool) -> list[dict]:
    """Every point of the design `x` measured (`measure`) under its estimates, each kept in `folder`
    as it is done; a point kept there already is read, not measured again."""
    points, first = [], True
    bar = tqdm(total=len(x), desc="sensitivity", unit="point", disable=not progress)
    with bar:
        for i, u in enumerate(x):
            path = folder / f"point-{i:03d}.json"
            if path.is_file():
                points.append(json.loads(path.read_text()))
                bar.update()
                continue
            t0 = time.perf_counter()
            values = point_values(u, groups)
            point = folder / f"point-{i:03d}"
            estimates.override(values)
            try:
                responses, side = measure(point, preset)
            finally:
                estimates.override({})
            shutil.rmtree(point, ignore_errors=True)
            result = {
                "u": [float(v) for v in u],
                "values": values,
                "responses": responses,
                "side": side,
                "wall_s": time.perf_counter() - t0,
            }
            results_files.write_json(path, result)
            points.append(result)
            bar.update()
            if first:
                bar.write(
                    f"first point: {result['wall_s']:.0f} s; about "
                    f"{result['wall_s'] * (len(x) - i - 1) / 60:.0f} min left"
                )
                first = False
    return points


def run(
    *,
    preset: str = PRESET,
    trajectories: int = TRAJECTORIES,
    groups: Sequence[str] | None = None,
    seed: int = 0,
    where: Location = Location(),
    progress: bool = True,
) -> dict[str, Any]:
    """Screen the chosen groups (all by default) over `trajectories` Morris trajectories on
    `preset`; writes results/sensitivity.{md,json,png} and returns the JSON."""
    known = screened_groups()
    groups = tuple(groups or known)
    unknown = [g for g in groups if g not in known]
    if unknown:
        raise UserError(f"unknown estimate groups {unknown}; those with an estimate to move: {list(known)}")
    if len(groups) < 2:
        raise UserError("a Morris screening needs at least two groups")
    presets.get(preset)
    x = design(groups, trajectories, seed)
    folder = _points_folder(where, preset, groups, trajectories, seed, x)
    n_trials = len(presets.get(preset).dataset.trials())
    print(
        f"Sensitivity: {len(groups)} groups x {trajectories} trajectories = {len(x)} points; each simulates "
        f"the {preset} preset "
        f"({n_trials} trials) and fits {len(PROBE_ROWS) + len(PROPERTIES)} probes. {prior_estimate(preset, len(x))}",
        flush=True,
    )
    t_start = time.perf_counter()
    points = _measure_points(folder, x, groups, preset, progress)
    doc = document(groups, x, points, seed)
    doc = {
        **documents.header(
            STUDY,
            module=__name__,
            command=where.command,
            preset=preset,
            trajectories=trajectories,
            levels=LEVELS,
            wall_s=time.perf_counter() - t_start,
        ),
        **doc,
    }
    with atomic.together():  # the figure, Markdown and JSON of this run, or none of them
        figure = plot(where.results_dir() / "sensitivity.png", doc)
        doc = results_files.write(where.results_dir(), doc, markdown, [figure])
    documents.replace_block(
        where.results_dir() / "REPORT.md", REPORT_BEGIN, REPORT_END, report_block(where.results_dir())
    )
    return doc


def document(groups: Sequence[str], x: np.ndarray, points: Sequence[Mapping[str, Any]], seed: int) -> dict[str, Any]:
    names = list(points[0]["responses"])
    y = {n: np.array([p["responses"][n] for p in points], np.float64) for n in names}
    influence = {n: analyse(groups, x, y[n], seed) for n in names}
    claims = []
    for c in CLAIMS:
        held = [bool(c.holds(p["responses"], p["side"])) for p in points]
        mu = influence[c.response]["mu_star"]
        order = np.argsort(mu)[::-1]
        claims.append(
            {
                "claim": c.text,
                "response": c.response,
                "holds_at": int(sum(held)),
                "points": len(points),
                "range": [float(y[c.response].min()), float(y[c.response].max())],
                "deciding": [{"group": groups[j], "mu_star": mu[j]} for j in order[:3]],
            }
        )
    return {
        "groups": list(groups),
        "estimates": {g: [e.name for e in moved() if e.group == g] for g in groups},
        "held": {e.name: e.value for e in estimates.ESTIMATES.values() if e.calibrated is not None},
        "points": [dict(p) for p in points],
        "responses": {n: {"min": float(y[n].min()), "max": float(y[n].max()), **influence[n]} for n in names},
        "claims": claims,
    }


PLOTTED = (
    Response.probe_test("internal"),
    Response.probe_test("external"),
    Response.probe_test("proprio"),
    Response.probe_test("flow"),
    Response.probe_test(probing.SESSION + "image"),
    Response.day_share(probing.SESSION + "image"),
    Response.day_share("flow"),
    Response.fabric_share(probing.SESSION + "image"),
    Response.MINSOUND_CAFE_DROP,
    Response.PALM_CAFE_DROP,
    Response.PALM_CAFE_GAIN,
    Response.IMAGE_PROPERTY_MARGIN,
)


def plot(path: Path, doc: Mapping[str, Any]) -> Path:
    """A ranked bar chart of mu* (with its 95 % interval) per response, for the responses the claims
    and the camera turn on."""
    shown = [n for n in PLOTTED if n in doc["responses"]]
    panels = [(n, doc["responses"][n]) for n in shown]
    return plots.ranked_bars(
        path, doc["groups"], panels, "Influence of each group of estimates (Morris mu*, 95 % interval)"
    )


def verdict(holds_at: int, points: int) -> str:
    """What a claim's count of points says about the simulator's estimates."""
    if holds_at == 0:
        return "holds nowhere in the ranges: not the estimates' doing (the model, or physics the simulator leaves out)"
    if holds_at == points:
        return "holds throughout the ranges: no estimate decides it"
    return "decided by the estimates"


def claims_table(doc: Mapping[str, Any]) -> str:
    """Each claim: at how many points inside the declared ranges it holds, what that says, the
    response's range, and the groups that move it most."""
    body = [
        [
            c["claim"],
            f"{c['holds_at']} of {c['points']}",
            verdict(c["holds_at"], c["points"]),
            f"{c['range'][0]:.1f} to {c['range'][1]:.1f}",
            "; ".join(f"{d['group']} ({d['mu_star']:.1f})" for d in c["deciding"]),
        ]
        for c in doc["claims"]
    ]
    header = [
        "Paper's claim (what a probe can say)",
        "Holds at points",
        "So",
        "Its response over the points",
        "Groups that move it most (mu*)",
    ]
    return results_files.markdown_table(header, body)


def influence_table(doc: Mapping[str, Any]) -> str:
    groups = doc["groups"]
    body = []
    for n, r in doc["responses"].items():
        order = np.argsort(r["mu_star"])[::-1]
        body.append(
            [
                n,
                f"{r['min']:.1f} to {r['max']:.1f}",
                *[f"{r['mu_star'][j]:.1f} ± {r['mu_star_conf'][j]:.1f}" for j in range(len(groups))],
                groups[order[0]],
            ]
        )
    return results_files.markdown_table(["Response", "Over the points", *groups, "Most influential"], body)


REPORT_BEGIN = (
    "<!-- sensitivity: written by `python -m experiments.sensitivity` from sensitivity.json; edits are overwritten -->"
)
REPORT_END = "<!-- end of sensitivity -->"


def report_block(results: Path) -> str:
    """REPORT.md's section on the estimates: the claims table of the sensitivity study in
    `results`, or how to run it; between `REPORT_BEGIN` and `REPORT_END`."""
    try:
        doc = json.loads((Path(results) / f"{STUDY}.json").read_text())
        body = [
            f"Whether each claim a probe can speak to holds somewhere inside the simulator's declared "
            f"ranges, and which "
            f"estimates move it ([sensitivity.md](sensitivity.md), from `{doc['command']}`, {doc['date']}). "
            f"A claim that holds at "
            "no point is not the simulator's unknowns; one that holds at some points is decided by them.",
            "",
            claims_table(doc),
        ]
    except (OSError, ValueError, KeyError):
        body = [
            "The sensitivity study has not run in this folder: `python -m experiments.sensitivity "
            "--results=<this folder>` "
            "writes it (it simulates the reduced preset anew at every point: about an hour on 2 cores)."
        ]
    return "\n".join([REPORT_BEGIN, *body, REPORT_END])


def markdown(doc: Mapping[str, Any]) -> str:
    n = len(doc["points"])
    lines = [
        "# Sensitivity: what each finding depends on among the simulator's estimates",
        "",
        documents.header_markdown(doc, f"{doc['wall_s'] / 60:.1f} min in all"),
        f"Morris screening (SALib) of {len(doc['groups'])} groups of estimates over their declared ranges "
        f"([docs/simulator.md](../docs/simulator.md#the-estimates)): {doc['trajectories']} trajectories of a "
        f"{doc['levels']}-level grid, "
        f"{n} points, each the `{doc['preset']}` preset simulated anew and probed. mu*: the mean absolute "
        f"change of a response when its group moves "
        "across its ranges (in the response's unit), ± its bootstrap 95 % half-width; the groups' estimates:",
        "",
        *[f"- {g}: {', '.join(f'`{e}`' for e in doc['estimates'][g])}" for g in doc["groups"]],
        *[
            f"- held at its calibrated value ([calibration.md](calibration.md)): `{n}` = {v:g}"
            for n, v in doc["held"].items()
        ],
        "",
        "## The paper's claims against the estimates",
        "",
        claims_table(doc),
        "",
        "## Influence of each group on every response (mu*)",
        "",
        influence_table(doc),
        "",
        'Ranked charts: [sensitivity.png](sensitivity.png). "Above chance" is a one-sided binomial test on the test '
        "sequences, which treats the sequences of one trial as independent (they are not): read it as descriptive.",
    ]
    return "\n".join(lines) + "\n"
