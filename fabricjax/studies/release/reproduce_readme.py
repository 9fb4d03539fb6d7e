"""README's results block: the headline numbers of a results folder, as data (`headline`, written
as `reproduce_plan.HEADLINE`) and as the Markdown between `README_BEGIN` and `README_END`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

from fabricjax import presets
from fabricjax.reporting import results_files, stats
from fabricjax.studies.machinery import documents, findings, probing
from fabricjax.studies.release.reproduce_plan import REPORT, STUDIES, UNSEEDED, minutes, read_json, title
from fabricjax.studies.release.staleness import other_stale, stale

# README's results block lies between these lines; `reproduce.run` rewrites it in the README.md
# beside the results folder
README_BEGIN = (
    "<!-- results: written by `python -m experiments.reproduce` from results/headline.json; edits are overwritten -->"
)
README_END = "<!-- end of results -->"


def headline(
    out: Path, manifest: Mapping[str, Any], preset: str, command_line: str | None, data: str | None
) -> dict[str, Any] | None:
    """README's results block as data, from the same results files as REPORT.md: the ablation's
    rows (the paper's rows on simulated data, every row on recorded data) beside the paper and
    the linear probe of the same inputs, each seeded study's checklist count, the stale studies
    (`stale` under today's fingerprints, on recorded data of contents `data`) by title, and the
    run's command, date, machine and wall time. None when the folder holds no ablation."""
    docs = {s: read_json(out / f"{s}.json") for s in STUDIES if s in manifest}
    abl = docs.get("ablation")
    if not abl:
        return None
    recorded = documents.recorded(abl)
    probe_rows = (docs.get("probe") or {}).get("rows", [])
    rows = []
    for r in abl["rows"]:
        if not recorded and r.get("fusion_norm", "sequence_minmax") != "sequence_minmax":
            continue  # our fusion variants: in REPORT.md, not the headline
        p = probing.row_for(
            r["modalities"],
            probe_rows,
            r.get("config", {}).get("image_reference"),
            rotated=r.get("config", {}).get("augment_rotation", False),
        )
        probe_test = None if p is None or p["accuracy"].get("test") is None else 100 * p["accuracy"]["test"]
        rows.append(
            {
                "inputs": r["display_name"],
                "ours": stats.format_mean_sd(r["accuracy"]["test"]["fabric"])
                + findings.collapse_text(r["collapsed"]["test"]),
                "paper": None if recorded else f"{r['paper_mean']:.2f} ± {r['paper_sd']:.2f}",
                "probe": None
                if probe_test is None
                else f"{probe_test:.2f}" + findings.collapse_text(p.get("collapsed", {}).get("test", [])),
            }
        )
    claims = {}
    for study, doc in docs.items():
        if doc and study not in UNSEEDED and study != "decide" and doc.get("findings") and not recorded:
            held, evaluated = findings.count([findings.Finding.from_json(f) for f in doc["findings"]])
            claims[title(study)] = (
                "not counted (install check)" if presets.install_check(preset) else f"{held} of {evaluated}"
            )
    m = abl["machine"]
    return {
        "command": command_line,
        "preset": preset,
        "recorded": recorded,
        "date": results_files.utc_now(),
        "code": results_files.git_commit(),
        "machine": documents.machine_line(m),
        "wall_s": sum(e["wall_s"] for s, e in manifest.items() if s in STUDIES),
        "seeds": len(abl["seeds"]),
        "rows": rows,
        "claims": claims,
        "stale": {title(s, recorded): note for s, note in stale(manifest, data).items()},
        "other_stale": len(other_stale(out, manifest)),
    }


def readme_block(head: Mapping[str, Any], results: str = "results") -> str:
    """README's results block (between `README_BEGIN` and `README_END`, both included) rendered
    from `headline`'s data; `results`: the results folder, relative to the README."""
    command_line = f"`{head['command']}`" if head["command"] else "a call from Python"
    lines = [
        README_BEGIN,
        f"From {command_line} on the {head['preset']} preset, {head['date']}, on {head['machine']} ({head['code']}); "
        f"its studies took {minutes(head['wall_s'])}. Every table, figure, test and time: "
        f"[{results}/{REPORT}]({results}/{REPORT}).",
        "",
    ]
    paper = not head["recorded"]
    header = [
        "Inputs",
        f"Ours, test [%] ({head['seeds']} seeds)",
        *(["Paper [%]"] if paper else []),
        "Linear probe, test [%]",
    ]
    body = [[r["inputs"], r["ours"], *([r["paper"]] if paper else []), r["probe"] or "–"] for r in head["rows"]]
    lines.append(results_files.markdown_table(header, body))
    if head["claims"]:
        lines.append("The paper's claims reproduced: " + "; ".join(f"{k} {v}" for k, v in head["claims"].items()) + ".")
        lines.append("")
    if head.get("stale"):  # a headline written before it recorded stale studies has none
        lines.append(
            "**Stale**, not today's numbers: "
            + "; ".join(f"{k} ({v})" for k, v in head["stale"].items())
            + " (`python -m experiments.reproduce --check` lists their files)."
        )
        lines.append("")
    if head.get("other_stale"):
        lines.append(
            f"{head['other_stale']} other results files in `{results}/` (studies run alone, sweeps, "
            f"benchmarks) predate today's "
            "code or estimates: `python -m experiments.reproduce --check --results=results` names each."
        )
        lines.append("")
    lines.append(README_END)
    return "\n".join(lines)


def write_readme_block(readme: Path, block: str) -> bool:
    """Replace the results block of `readme` with `block`; False (nothing written) when the file
    does not exist or has no block: only a README that asks for one is ever written."""
    return documents.replace_block(readme, README_BEGIN, README_END, block)
