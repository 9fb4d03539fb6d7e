"""The results layer of the studies: what a study's results file says about where its numbers
come from.

Every study (the training studies, the probe, cost, sweep, latents, stream, palm) builds its JSON
document on `header` (`results_files.header`: study, command, code and the fingerprints of what
decides its numbers, machine, date; then the fields it adds: preset, seeds, dataset, ...), says
where its numbers come from in Markdown with `header_markdown` and writes results/<study>.md and
.json atomically with `results_files.write`, which also records the figures it drew under one
key, "figures". Tables are `results_files.markdown_table`; per-row and per-sample records of a
trained row are `trained.TrainedRow.doc` and `samples_doc`. The paper's claims checked on a
study's rows live in `findings`; REPORT.md, which gathers every study, is `reproduce_report`'s.
What every results file shares, the benchmarks' included (header fields, machine, code, atomic
writing, tables), is `fabricjax.reporting.results_files`, beneath; the studies call it by that name."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Iterable, Sequence

from fabricjax import presets
from fabricjax.reporting import results_files, stats
from fabricjax.sequences import data
from fabricjax.store import dataset_index, provenance, workspace
from fabricjax.studies.machinery.loading import Dataset


def data_fingerprint(ds: Dataset | None) -> str | None:
    """The "data" of `fingerprints` for a study that read `ds`: recorded data's contents, else None."""
    return dataset_index.load_index(ds.folder, ds.workdir).content_hash if ds is not None and ds.recorded else None


def header(
    study: str,
    *,
    module: str,
    command: str | None,
    seeds: Sequence[int] | None = None,
    dataset: Dataset | None = None,
    compute_dtypes: Iterable[str] | None = None,
    **fields,
) -> dict[str, Any]:
    """The first fields of every results JSON: what ran (`study`; `module`: the module that
    computes it; `command`: the command line, None when called from Python), from which code and
    with which `fingerprints`, when and on which machine, then the study's own `fields` (its
    preset, the seeds, the dataset it read as `dataset_doc`, the compute dtypes its models trained
    in (`Config.compute_dtype`), its times, ...)."""
    doc = results_files.header(study, module=module, command=command, data=data_fingerprint(dataset))
    if seeds is not None:
        doc["seeds"] = list(seeds)
    if dataset is not None:
        doc["dataset"] = dataset_doc(dataset)
    if compute_dtypes is not None:
        doc["compute_dtype"] = sorted(set(compute_dtypes))
    return {**doc, **fields}


def header_markdown(doc: dict[str, Any], time: str | None = None) -> str:
    """Where the numbers come from, as a list: command, code and date, preset and data, seeds,
    machine, and `time` (default: a training study's training and data times)."""
    lines = [command_markdown(doc["command"])]
    if "code" in doc:  # results written before the header named its code and date have neither
        lines.append(f"- code: {doc['code']}; written {doc['date']}")
    if "fingerprints" in doc:  # nor, before it recorded them, fingerprints
        lines.append(fingerprints_markdown(doc["fingerprints"]))
    if "dataset" in doc:
        lines.append(data_markdown(doc["preset"], doc["dataset"]))
    if "seeds" in doc:
        seeds = doc["seeds"]
        lines.append(f"- seeds: {len(seeds)} ({seeds[0]}-{seeds[-1]}), mean ± SD (sample SD) over seeds")
    if "compute_dtype" in doc:
        lines.append(
            f"- arithmetic: matrix products in {' and '.join(doc['compute_dtype'])} with float32 "
            f"accumulation; parameters, normalisations, losses and statistics in float32"
        )
    lines.append(machine_markdown(doc["machine"]))
    if time is None and "train_s" in doc:
        time = (
            f"training {doc['train_s']:.0f} s in all (per row below, compilation included); "
            f"{data_time_markdown(doc['dataset'])}"
        )
    if time:
        lines.append(f"- time: {time}")
    return "\n".join([*lines, ""])


def fingerprints_markdown(prints: dict[str, str | None]) -> str:
    """The `fingerprints` a results file records, as its header lists them."""
    named = results_files.FINGERPRINT_KINDS
    return "- fingerprints: " + ", ".join(f"{named[k].listed} `{v}`" for k, v in prints.items() if v is not None)


def replace_block(path: Path, begin: str, end: str, block: str) -> bool:
    """Replace the lines from `begin` to `end` in the file `path` with `block` (which carries both
    markers again); False (nothing written) when the file does not exist or lacks the markers."""
    try:
        text = Path(path).read_text()
    except OSError:
        return False
    start, stop = text.find(begin), text.find(end)
    if start < 0 or stop < start:
        return False
    results_files.write_text(path, text[:start] + block + text[stop + len(end) :])
    return True


def data_time_markdown(d: dict[str, Any]) -> str:
    """The data's share of a study's time (`dataset_doc`): recorded data is read, never simulated."""
    load = f"features and sequences {d['load_s']:.0f} s" + (
        f", camera inputs laid out for training {d['layout_s']:.1f} s" if d.get("layout_s") else ""
    )
    if d["source"] == "recorded":
        return f"data apart from that: {load} (recorded data, read as it is)"
    return f"data apart from that: simulation {d['generate_s']:.0f} s, {load}"


def data_markdown(preset: str, d: dict[str, Any]) -> str:
    """The preset and the dataset (`dataset_doc`) a study read."""
    if d["source"] == "recorded":
        line = (
            f"- preset: {preset}; recorded data `{d['folder']}` ({len(d['classes'])} classes, chance "
            f"{100 / len(d['classes']):.1f} %); trials {d['trials']}; sequences {d['sequences']}"
        )
        return line + ("\n" + provenance.markdown(d["provenance"]) if "provenance" in d else "")
    return f"- preset: {preset}; {d['source']} dataset `{d['folder']}`; sequences {d['sequences']}"


def machine_line(m: dict[str, Any]) -> str:
    """The machine (`machine`) in a few words: its CPU, cores and JAX's devices."""
    return f"{m['cpu']}, {m['cores']} cores, JAX {m['jax']} on {m['jax_backend']} ({len(m['devices'])} devices)"


def machine_markdown(m: dict[str, Any]) -> str:
    """The machine (`machine`) a study ran on."""
    return (
        f"- machine: {m['cpu']} ({', '.join(m.get('vector_units') or ['vector units not recorded'])}), "
        f"{m['cores']} cores, "
        f"JAX {m['jax']} on {m['jax_backend']} ({len(m['devices'])} devices)"
    )


def command_markdown(command: str | None) -> str:
    return f"- command: `{command}`" if command else "- command: none (called from Python)"


def samples_doc(ss: data.SequenceSet) -> dict[str, Any]:
    """What each evaluated sequence is: labels and where it comes from (the predictions' columns)."""
    return {
        "labels": {k: v.tolist() for k, v in ss.labels.items()},
        **{k: ss.info[k].tolist() for k in ("fabric_id", "trial_key", "start")},
    }


def dataset_doc(ds: Dataset) -> dict[str, Any]:
    return {
        "folder": workspace.shown(ds.folder),
        "source": ds.source,
        "generate_s": ds.generate_s,
        "load_s": ds.load_s,
        "layout_s": ds.layout_s,
        "sequences": {k: len(v) for k, v in ds.sets.items()},
        "trials": {k: c["trials"] for k, c in ds.split_counts().items()},
        "classes": list(ds.classes),
        **(
            {"names": dict(next(iter(ds.sets.values())).names)} if ds.recorded else {}
        ),  # how the data names its streams
        **(
            {"provenance": source} if ds.recorded and (source := provenance.read(ds.folder)) else {}
        ),  # its README's source and terms
    }


def stream_names(doc: dict[str, Any]) -> dict[str, str]:
    """{modality: the data's name for its stream} of a results document on recorded data (the rig
    file's microphones and joints, `data.inputs_name` names rows by them); {} otherwise: the paper's names."""
    return dict(doc.get("dataset", {}).get("names", {})) if recorded(doc) else {}


def recorded(doc: dict[str, Any]) -> bool:
    """The results are of recorded data (`--data_dir`): compared row with row, never with the
    paper's numbers or the simulator's."""
    return doc["dataset"]["source"] == "recorded"


def title(doc: dict[str, Any], study: str, paper: str | None = None) -> str:
    """A study's heading: on recorded data it names the data, not what of the paper (`paper`, e.g.
    "Table ablation_table"; None: nothing of the paper's) it reproduces; on an install-check
    preset (smoke) it is followed by the note that says so."""
    if recorded(doc):
        return f"# {study} on recorded data"
    heading = f"# {study} (the paper's {paper})" if paper else f"# {study}"
    return heading + (f"\n\n> {presets.note(doc.get('preset'))}" if counts_no_claims(doc) else "")


def counts_no_claims(doc: dict[str, Any]) -> bool:
    """The results are of a preset whose results are not the paper's table (`presets.note`: the
    install check, a sample of the paper's data): the paper's claims are shown as checks that run,
    never counted."""
    return presets.note(doc.get("preset")) is not None


BEST_GAP = "Row − best row [pp]"  # the column recorded-data tables have instead of the paper's
RECORDED_NOTE = "Rows are compared with each other on the same recorded data and test trials."


def best_gaps(means: Sequence[float]) -> list[str]:
    """Each row's mean [%] minus the best row's: how rows on recorded data are compared."""
    best = max(means)
    return [f"{m - best:+.2f}" for m in means]


def wilcoxon_doc(w: stats.WilcoxonResult) -> dict[str, Any]:
    return {**dataclasses.asdict(w), "describe": w.describe()}
