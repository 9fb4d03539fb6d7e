"""REPORT.md: every study of a results folder's manifest in one page.

The report embeds each study's own Markdown (its table beside the paper's, its findings
checklist, its Wilcoxon tests), links its figures, sets the probe beside the ablation row by row
(from both studies' JSON, `pages.probe.beside_ablation`), and adds a summary of every checklist, the
machine, the library versions, the code's fingerprint, each study's wall time and the exact
command that reruns that study alone; a stale study (`staleness.stale`) says so. On recorded
data (`data_dir`) the report, like its studies, names the data and compares rows with each
other: no paper in its titles or summary.
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path
from typing import Any, Mapping

import fabricjax
from fabricjax import presets
from fabricjax.reporting import results_files
from fabricjax.studies.machinery import documents, findings
from fabricjax.studies.diagnostics import sensitivity
from fabricjax.studies.pages import probe as probe_page
from fabricjax.studies.release.reproduce_plan import STUDIES, UNSEEDED, minutes, read_json, title
from fabricjax.studies.release.staleness import stale


def versions() -> dict[str, str]:
    out = {}
    for name in (
        "jax",
        "jaxlib",
        "flax",
        "optax",
        "orbax-checkpoint",
        "numpy",
        "scipy",
        "opencv-contrib-python-headless",
        "scikit-learn",
    ):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def _demote(markdown: str) -> str:
    """A study's Markdown inside the report: its title dropped, its sections one level down."""
    lines = markdown.splitlines()
    if lines and lines[0].startswith("# "):
        lines = lines[1:]
    return "\n".join("#" + line if line.startswith("#") else line for line in lines).strip() + "\n"


def _summary_row(
    study: str, doc: Mapping[str, Any], entry: Mapping[str, Any], note: str | None, preset: str, recorded: bool
) -> list:
    """A study's line of the summary table: its title, seeds, claims reproduced (not on recorded
    data), wall time and when it finished, with its stale `note` (None: up to date)."""
    if study in UNSEEDED:  # not a table of the paper: no claims to check, no seeds
        seeds, claims = "– (deterministic)", "– (not in the paper)"
    elif study == "decide":  # not in the paper: the ablation's models, each its best seed
        seeds, claims = "1 per model (best of the ablation's)", "– (not in the paper)"
    else:
        held, evaluated = findings.count([findings.Finding.from_json(f) for f in doc.get("findings", [])])
        seeds = len(doc["seeds"]) if study != "latents" and doc.get("seeds") else "1 (best of the property study's)"
        claims = f"{held} of {evaluated}" if not presets.install_check(preset) else "not counted (install check)"
    finished = entry["finished"] + (f"; **{note}**" if note else "")
    return [
        f"[{title(study, recorded)}](#{_anchor(title(study, recorded))})",
        seeds,
        *([] if recorded else [claims]),
        minutes(entry["wall_s"]),
        finished,
    ]


def _heading(first: Mapping[str, Any] | None, preset: str, recorded: bool) -> tuple[str, str, str]:
    """(the report's heading, what the first study's time includes, what its numbers are)."""
    if recorded:
        heading = documents.title(first, f"Report: every study on the {preset} preset")
        data_note, numbers = "feature extraction, done once, is", documents.RECORDED_NOTE
    else:
        heading = f"# Reproduction report: every table and figure of the paper on the {preset} preset"
        if presets.install_check(preset):
            heading += f"\n\n> {presets.INSTALL_CHECK_NOTE}"
        data_note = "data simulation and feature extraction, done once, are"
        numbers = (
            "The simulator is the same for every study and was never tuned to a table: differences from the paper "
            "are findings."
        )
    return heading, data_note, numbers


def _study_section(study: str, out: Path, manifest: Mapping[str, Any], docs, notes, recorded: bool) -> list[str]:
    """A study's section: its time and command, whether it is stale, its page and any figure the
    page does not show; the probe's also sets it beside the ablation's rows."""
    e = manifest[study]
    md = out / f"{study}.md"
    lines = [
        f"## {title(study, recorded)}",
        "",
        f"Wall time {minutes(e['wall_s'])}, finished {e['finished']}. Rerun alone: `{e['command']}`",
        "",
        *(
            [
                f"> **{notes[study][0].upper() + notes[study][1:]}**: these are not today's numbers; "
                f"`python -m experiments.reproduce` reruns it.",
                "",
            ]
            if study in notes
            else []
        ),
        _demote(md.read_text()) if md.exists() else f"({md.name} is missing)\n",
    ]
    figures = (docs[study] or {}).get("figures", [])
    lines += [
        f"![{f}]({f})\n"
        for f in figures
        if (out / f).exists() and f"({f})" not in (md.read_text() if md.exists() else "")
    ]
    if study == "probe" and docs["probe"] and docs.get("ablation"):
        lines += [
            "### The probe beside the model, row by row",
            "",
            probe_page.beside_ablation(docs["probe"], docs["ablation"]),
        ]
    return lines


def write_report(
    path: Path,
    manifest: Mapping[str, Any],
    preset: str,
    data: str | None,
    command_line: str,
    run_s: float,
    n_run: int,
) -> Path:
    """REPORT.md over every study the manifest holds (this call's and earlier calls'), in `STUDIES`
    order, each stale one (`stale` under today's fingerprints, on recorded data of contents `data`,
    None for simulated data) saying so."""
    out = path.parent
    studies = [s for s in STUDIES if s in manifest]
    notes = stale(manifest, data)
    docs = {s: read_json(out / f"{s}.json") for s in studies}
    first = next((d for d in docs.values() if d), None)
    m = first["machine"] if first else results_files.machine()
    # recorded data (`--data_dir`): its studies compare rows with each other, so no paper in titles or summary
    recorded = first is not None and documents.recorded(first)
    total = sum(e["wall_s"] for e in manifest.values())
    summary = [
        _summary_row(study, docs[study] or {}, manifest[study], notes.get(study), preset, recorded) for study in studies
    ]
    heading, data_note, numbers = _heading(first, preset, recorded)
    lines = [
        heading,
        "",
        f"- command: `{command_line}` ({n_run} of {len(studies)} studies run by this call, in {minutes(run_s)}; "
        "the others were up to date and kept)",
        f"- machine: {m['cpu']}, {m['cores']} cores, {m['platform']}, Python {m['python']}, JAX on "
        f"{m['jax_backend']} ({len(m['devices'])} devices)",
        f"- versions: {', '.join(f'{k} {v}' for k, v in versions().items())}",
        f"- code: fabricjax {fabricjax.__version__}, {results_files.git_commit()}",
        documents.fingerprints_markdown(results_files.data_fingerprints(data))
        + " (today's; each study's header gives the code's, of the module that computes it; "
        "`python -m experiments.reproduce --check` lists the studies whose fingerprints moved)",
        f"- wall time of the studies: {minutes(total)} in all (each below; {data_note} in the first study's)",
        "",
        f"Every number below comes from the study's results file in this folder, written by the run named "
        f"beside it. {numbers}",
        "",
        "## Summary",
        "",
        results_files.markdown_table(
            ["Study", "Seeds", *([] if recorded else ["Paper's claims reproduced"]), "Wall time", "Finished"], summary
        ),
        "",
    ]
    if not recorded:
        lines += ["## What the simulator's estimates decide", "", sensitivity.report_block(out), ""]
    for study in studies:
        lines += _study_section(study, out, manifest, docs, notes, recorded)
    return results_files.write_text(path, "\n".join(lines))


def _anchor(title: str) -> str:
    """GitHub's anchor for a heading: lower case, spaces to hyphens, punctuation dropped."""
    return "".join(c for c in title.lower().replace(" ", "-") if c.isalnum() or c in "-_")
