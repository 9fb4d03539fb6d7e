"""The plan of `experiments.reproduce`: every table and figure of the paper on one preset, in order.

`PLAN` (data): the modality ablation (5 seeds), the linear probe of every ablation row's inputs
(no seeds: deterministic, and cheap), the day shift of every input (what the fabric, the day and
the trial explain, beside the probe's training-day and new-day accuracy; no seeds), the PSD
bandwidth (5), cafe noise (10, as the paper), property perception (5, saving its checkpoints)
and the latent t-SNE from the property study's checkpoint of its Minsound + proprioception +
Minsight row, then the decision study (calibration, when to stop rubbing, unknown fabrics) on the
ablation's checkpoints of the row the paper calls best and of Minsound alone (`DECIDE_ROWS`; no
training), then what moves Minsight's imaged wall over a stroke and what optical flow sees of it
(`flow_budget`), and last what Minsight's camera sees of a stroke (`camera_frames`); these two
render the simulator's frames: no data, no training. The dataset is simulated once (or read from `data_dir`), features
and compiled programs are cached, checkpoints resume, so every study after the first pays only
for its training.

On recorded data the plan follows what the data has (`fit_plan`): a study's rows that need a
stream the data lacks are left out, a study none of whose rows it can feed is skipped, and the
studies of the paper's protocol (`PROTOCOL`: cafe noise needs cafe-split trials, the property
study held-out fabrics, the latents the property study, the decision study the ablation) are
skipped when the data has no such trials, and the studies of the simulator itself
(`SIMULATOR_ONLY`: the flow budget, the camera frames) always, each with one line saying why.

Each step reruns alone by the command `command` gives; `estimate_s` expects its wall time from
an earlier run's manifest. The files a run keeps in its results folder: the manifest
(`MANIFEST`), the report (`REPORT`), README's results block as data (`HEADLINE`) and each
study's own (`outputs`).
"""

from __future__ import annotations

import dataclasses
import json
import shlex
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from fabricjax import presets
from fabricjax.config import format_override
from fabricjax.errors import UserError
from fabricjax.store import archive, dataset_index, provenance, splits
from fabricjax.studies.machinery import ablation_rows
from fabricjax.studies.machinery.rows import split_by_inputs
from fabricjax.studies.diagnostics import camera_frames, day_shift, decide, flow_budget, probe
from fabricjax.studies.paper import ablation, bandwidth, latents, noise, properties

STUDIES = {
    "ablation": ablation,
    "probe": probe,
    "day_shift": day_shift,
    "bandwidth": bandwidth,
    "noise": noise,
    "properties": properties,
    "latents": latents,
    "decide": decide,
    "flow_budget": flow_budget,
    "camera_frames": camera_frames,
}
# a study -> the study whose results it reads
UPSTREAM = {"latents": "properties", "day_shift": "probe", "decide": "ablation"}
# deterministic studies of no paper table: no seeds, no claims
UNSEEDED = ("probe", "day_shift", "flow_budget", "camera_frames")
SIMULATOR_ONLY = ("flow_budget", "camera_frames")  # studies of the simulator itself: skipped on recorded data
# the paper's figure: its "Minsound + Minsight" model, which also reads proprioception
LATENT_ROW = properties.ROWS[-1].name
# the decision study's models: the ablation row the paper calls best (its highest mean) and Minsound alone
DECIDE_ROWS = (max(ablation_rows.PAPER_ROWS, key=lambda r: r.paper["mean"]).name, "internal")
# studies of another study's checkpoints: run by --checkpoint, no seeds or rows flags
CHECKPOINT_STUDIES = ("latents", "decide")
MANIFEST = "reproduce.json"
REPORT = "REPORT.md"
HEADLINE = "headline.json"  # README's results block, as data (tracked, unlike the studies' JSON)


@dataclasses.dataclass(frozen=True)
class Step:
    """One study of the plan: its name (a key of `STUDIES`), seed count and rows (None: all)."""

    study: str
    seeds: int | None = (
        None  # None for `UNSEEDED` (deterministic) and the studies of another's checkpoints (latents, decide)
    )
    rows: tuple[str, ...] | None = None


PLAN = (
    Step("ablation", 5),
    Step("probe"),
    Step("day_shift"),
    Step("bandwidth", 5),
    Step("noise", 10),
    Step("properties", 5),
    Step("latents"),
    Step("decide", rows=DECIDE_ROWS),
    Step("flow_budget"),
    Step("camera_frames"),
)
# The studies that need trials of the paper's protocol: the split they read, and what it is
PROTOCOL = {
    "noise": ("cafe", "trials of the cafe condition (split cafe)"),
    "properties": ("holdout", "held-out fabrics (split holdout)"),
}

# The manifest the repository publishes (results/reproduce.json): its recorded wall times are the
# estimate for a run of the same preset before this folder has its own.
PUBLISHED_MANIFEST = provenance.repository_root() / "results" / MANIFEST


def title(study: str, recorded: bool = False) -> str:
    """How the report names `study`: its title, and on simulated data what of the paper it reproduces."""
    module = STUDIES[study]
    return module.TITLE if recorded else f"{module.TITLE} ({module.PAPER})"


def refuse_unknown(studies: Sequence[str]) -> None:
    """A one-line error naming the studies of `studies` that are not of `STUDIES`, and those that are
    (before anything runs or is read, so a misspelt name is never a silent no-op)."""
    unknown = [s for s in studies if s not in STUDIES]
    if unknown:
        raise UserError(f"--studies: unknown studies {unknown}; choose from {', '.join(STUDIES)}")


def chosen(studies: Sequence[str] | None) -> tuple[Step, ...]:
    """The steps of `PLAN` of the studies named in `studies` (None: all), in the plan's order."""
    refuse_unknown(studies or ())
    return tuple(s for s in PLAN if studies is None or s.study in studies)


def fit_plan(plan: Sequence[Step], preset: str, data_dir, workdir, say: Callable[[str], None]) -> list[Step]:
    """`plan` as recorded data in `data_dir` can run it (module docstring), saying what is left out."""
    index = dataset_index.load_index(data_dir, workdir)
    lay = archive.layout(index.entries[0].meta)
    have = set(lay.modalities())
    roles = set(splits.assign_roles([e.meta for e in index.entries], presets.get(preset).dataset.splits))
    out: list[Step] = []
    for step in plan:
        if step.study in SIMULATOR_ONLY:
            say(f"  {step.study:<11} skip  (it draws the simulator's frames, not the data's)")
            continue
        if step.study == "latents" and not any(s.study == "properties" for s in out):
            say("  latents     skip  (it reads the property study's checkpoint, which this data does not train)")
            continue
        if step.study == "decide":
            ablated = next((s for s in out if s.study == "ablation"), None)
            fit = tuple(
                r for r in step.rows or () if ablated is not None and (ablated.rows is None or r in ablated.rows)
            )
            if not fit:
                say(
                    "  decide      skip  (it reads the ablation's checkpoints of its rows, which this data "
                    "does not train)"
                )
                continue
            out.append(dataclasses.replace(step, rows=fit))
            continue
        if step.study in PROTOCOL and PROTOCOL[step.study][0] not in roles:
            say(
                f"  {step.study:<11} skip  (the paper's protocol: it needs {PROTOCOL[step.study][1]}, and "
                f"the data has none)"
            )
            continue
        rows = getattr(STUDIES[step.study], "ROWS", None)
        if rows is None:
            out.append(step)
            continue
        named = [r for r in rows if step.rows is None or r.name in step.rows]
        fed, lacking = split_by_inputs(named, have)
        fit = tuple(r.name for r in fed)
        if not fit:
            say(
                f"  {step.study:<11} skip  (its rows need {', '.join(lacking)}, which the data lacks: it has "
                f"{lay.describe()})"
            )
            continue
        if len(fit) < len(named):
            say(
                f"  {step.study:<11} {len(named) - len(fit)} of its {len(named)} rows left out (they need "
                f"{', '.join(lacking)}, which the data lacks)"
            )
        out.append(step if len(fit) == len(named) else dataclasses.replace(step, rows=fit))
    return out


def command(
    step: Step,
    preset: str,
    overrides: Mapping[str, Any],
    results: Path,
    checkpoint: str | None = None,
    data_dir=None,
    workdir=None,
) -> str:
    """The command that reruns `step` alone, as a user would type it (`checkpoint`: the
    checkpoint folders, comma-separated, of a study of another's checkpoints)."""
    args = [f"python -m experiments.{step.study}"]
    if step.study in CHECKPOINT_STUDIES:
        args.append(f"--checkpoint={checkpoint}")
    else:
        args += (
            [f"--seeds={step.seeds}"] * bool(step.seeds)
            + [f"--preset={preset}"]
            + ([f"--rows={','.join(step.rows)}"] if step.rows else [])
        )
        args += [shlex.quote(f"--set={format_override(k, v)}") for k, v in sorted(overrides.items())]
    args += (
        [f"--data_dir={data_dir}"] * bool(data_dir)
        + [f"--workdir={workdir}"] * bool(workdir)
        + [f"--results={results}"]
    )
    return " ".join(args)


def estimate_s(step: Step, preset: str, *manifests: Mapping[str, Any]) -> float | None:
    """Expected wall time of `step`: the first of `manifests` that recorded this study on `preset`,
    scaled by seeds and rows (None where none did)."""
    entry = next((m[step.study] for m in manifests if m.get(step.study, {}).get("preset") == preset), None)
    if entry is None:
        return None
    scale = (
        (step.seeds or 1)
        / (entry["seeds"] or 1)
        * (len(step.rows) if step.rows else n_rows(step.study))
        / entry["rows"]
    )
    return entry["wall_s"] * scale


def n_rows(study: str) -> int:
    """Rows a study trains without --rows (1 for the latents, which have none)."""
    module = STUDIES[study]
    default = getattr(getattr(module, "STUDY", None), "default_rows", None)
    return len(default if default is not None else getattr(module, "ROWS", (None,)))


def minutes(seconds: float | None) -> str:
    return "unknown" if seconds is None else f"{seconds / 60:.1f} min"


def read_json(path: Path) -> dict[str, Any] | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def outputs(study: str, out: Path) -> list[Path]:
    """The study's Markdown and JSON, and every figure its JSON names (a row subset may draw none)."""
    doc = read_json(out / f"{study}.json") or {}
    return [out / f"{study}.md", out / f"{study}.json", *[out / f for f in doc.get("figures", [])]]
