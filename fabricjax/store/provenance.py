"""Where recorded data comes from and on what terms, as its own README says, kept beside its archives.

An importer given a manifest reads the README beside it (README, README.txt or README.md) and
keeps its title line, its first section (what was recorded, by whom: what its terms ask to cite)
and the sections that say where the data comes from and on what terms (headed Source, License /
Licence, Citation / Cite) in `<out>/data_source.json`; every results
page of that folder quotes them at its top. The text is the data's own, verbatim: fabricjax adds
nothing to what it says.

A section is a heading and the lines under it: a Markdown heading (`# ...`) and the lines up to
the next, or, in a plain-text README, a line at the margin and the indented lines below it.
"""

from __future__ import annotations

import json
import os
import shlex
import sys
from pathlib import Path
from typing import Any

from fabricjax.store import atomic

FILE = "data_source.json"
READMES = ("README", "README.txt", "README.md")
KEPT = ("source", "licen", "citation", "cite")  # section headings (lower case) whose text is kept, by prefix


def repository_root() -> Path:
    """The folder the `fabricjax` package sits in: the checkout's root, holding the published
    results/ the plans and estimates read, and the tree whose commit results files name."""
    return Path(__file__).resolve().parents[2]


def program() -> list[str]:
    """This process's program as a user runs it: `python -m <module>` for a module of the
    repository, else its file's name."""
    main = Path(sys.argv[0]) if sys.argv and sys.argv[0] else Path("python")
    root = repository_root()
    if main.suffix == ".py" and main.resolve().is_relative_to(root):
        return ["python", "-m", ".".join(main.resolve().relative_to(root).with_suffix("").parts)]
    return [main.name]


def command_line() -> str:
    """This process's command as a user typed it (`python -m experiments.ablation ...`): recorded in
    results files and in the notes of the locks a run holds."""
    return shlex.join([*program(), *sys.argv[1:]])


def _sections(lines: list[str]) -> list[tuple[str, list[str]]]:
    markdown = any(line.startswith("#") for line in lines)
    out: list[tuple[str, list[str]]] = []
    for line in lines[1:]:
        heading = (
            line.startswith("#")
            if markdown
            else bool(line.strip()) and not line[0].isspace() and not set(line.strip()) <= set("=-")
        )
        if heading:
            out.append((line.lstrip("#").strip(), []))
        elif out and line.strip():
            out[-1][1].append(line.strip())
    return out


def from_readme(folder: str | os.PathLike) -> dict[str, Any] | None:
    """The provenance of the README in `folder` ({"readme", "title", "sections": {heading: text}}),
    or None where the folder has no README."""
    readme = next((Path(folder) / n for n in READMES if (Path(folder) / n).is_file()), None)
    if readme is None:
        return None
    lines = readme.read_text(errors="replace").splitlines()
    if not lines:
        return None
    sections = _sections(lines)
    kept = {
        h: " ".join(body) for i, (h, body) in enumerate(sections) if (i == 0 or h.lower().startswith(KEPT)) and body
    }
    return {"readme": readme.name, "title": lines[0].lstrip("#").strip(), "sections": kept}


def write(out: str | os.PathLike, doc: dict[str, Any]) -> None:
    """`doc` as `<out>/data_source.json`, whole or not at all."""
    with atomic.atomic_open(Path(out) / FILE, "w") as f:
        json.dump(doc, f, indent=1)


def read(folder: str | os.PathLike) -> dict[str, Any] | None:
    """The provenance an import kept in `folder`, or None (simulated data, or no README was given)."""
    try:
        return json.loads((Path(folder) / FILE).read_text())
    except (OSError, ValueError):
        return None


def markdown(doc: dict[str, Any]) -> str:
    """The provenance as a results page's header line: the title and each section kept."""
    parts = [f"**{h}**: {text}" for h, text in doc["sections"].items()]
    return f"- data: {doc['title']} (its {doc['readme']})" + ("; " + "; ".join(parts) if parts else "")
