"""The package's own source code, as one fingerprint: what produced a result or trained a model.

A config names what a run computes, not the code that computes it: a change in how training
rounds (the image rotation's, for one) moves results and leaves every config as it was. Results
(`studies.tools.reproduce`, and every results file's header: `studies.common.documents.fingerprints`)
and the studies' checkpoint folders (`studies.common.runner.checkpoint_dir`) are keyed with this
fingerprint, so that other code reruns instead of reusing what older code made.

It covers what the package executes: every module of `fabricjax` (the simulator, its registry of
estimates, the features, the data, the models, training and the studies, each result's Markdown
included), without comments, docstrings (a statement that is a string alone) and blank lines, so
that a change of documentation alone leaves results current. The command-line modules
(`experiments`, `acquisition`) are not in it: they parse flags and call the package.
"""

from __future__ import annotations

import functools
import hashlib
import io
import tokenize
from pathlib import Path

_STATEMENT_START = (tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT, None)  # None: the module's first token


def executed(text: str) -> str:
    """The source `text` of a module without its comments, docstrings and blank lines (trailing
    spaces dropped): what the fingerprint hashes of it."""
    tokens = [t for t in tokenize.generate_tokens(io.StringIO(text).readline) if t.type != tokenize.NL]
    cut = []  # (start, end) of each comment and docstring, as (row, column)
    for k, t in enumerate(tokens):
        before = tokens[k - 1].type if k else None
        after = tokens[k + 1].type if k + 1 < len(tokens) else tokenize.ENDMARKER
        if t.type == tokenize.COMMENT or (
            t.type == tokenize.STRING and before in _STATEMENT_START and after in (tokenize.NEWLINE, tokenize.ENDMARKER)
        ):
            cut.append((t.start, t.end))
    lines = text.splitlines(keepends=True)
    starts = [0]
    for line in lines:
        starts.append(starts[-1] + len(line))
    kept, at = [], 0
    for (r0, c0), (r1, c1) in cut:
        begin, end = starts[r0 - 1] + c0, starts[r1 - 1] + c1
        kept.append(text[at:begin])
        at = end
    kept.append(text[at:])
    return "\n".join(line.rstrip() for line in "".join(kept).splitlines() if line.strip()) + "\n"


@functools.cache
def fingerprint() -> str:
    """sha256 over every module of the `fabricjax` package: its path and what it executes
    (`executed`: without comments, docstrings and blank lines)."""
    h = hashlib.sha256()
    root = Path(__file__).resolve().parents[1]
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode() + b"\0" + executed(path.read_text()).encode() + b"\0")
    return h.hexdigest()
