"""The paper's qualitative claims as predicates over per-seed results: a findings checklist.

A study states each claim it can test as a `Finding`: the claim in words, whether our per-seed
results reproduce it (None when a row it needs was not run) and the numbers behind the verdict,
so a reader can disagree with the rule without rerunning anything. Claims compare seed means
unless they say otherwise; the rule is part of the claim's text.

Every accuracy is judged against the strongest trivial baseline of its split, `majority`: always
answering the split's most frequent class (or level), computed from its labels. The tables show it
beside each accuracy, with `collapse_text` wherever a seed predicts one class for nearly every
sequence (`COLLAPSED_SHARE`), and a claim that something is above chance counts only where its
mean over seeds is above that baseline (`above_majority`); 1 / classes is shown beside it.

A verdict counts only where its evidence can carry it (`counted_where`): a row that collapsed, or
whose mean is at or below its majority baseline, says nothing of what its inputs carry, so a
claim comparing it is shown with its verdict and not counted; nor is a claim about one of our
variant rows, which is reported beside the paper's claims and never as one of them.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from fabricjax.reporting import results_files
from fabricjax.studies.machinery import documents


@dataclasses.dataclass(frozen=True)
class Finding:
    """One claim of the paper checked against our per-seed results."""

    claim: str
    holds: bool | None  # None: not evaluated (a row the claim needs is missing)
    evidence: str
    not_counted: str = ""  # why the verdict does not count (`counted_where`); "" where it does

    @property
    def counted(self) -> bool:
        return self.holds is not None and not self.not_counted

    @property
    def verdict(self) -> str:
        said = {True: "reproduced", False: "not reproduced", None: "not evaluated"}[self.holds]
        return f"{said}, not counted" if self.holds is not None and self.not_counted else said

    def to_json(self) -> dict[str, Any]:
        return {
            "claim": self.claim,
            "holds": self.holds,
            "verdict": self.verdict,
            "evidence": self.evidence,
            "not_counted": self.not_counted,
        }

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> "Finding":
        return cls(doc["claim"], doc["holds"], doc["evidence"], doc.get("not_counted", ""))


def mean_pct(values) -> float:
    """Mean over seeds, in percent."""
    return 100.0 * float(np.mean(np.asarray(values, np.float64)))


def describe(name: str, values) -> str:
    """'name 91.2 % (seeds: 90.1, 92.0, ...)': a mean and the per-seed values it came from."""
    per_seed = ", ".join(f"{100 * v:.1f}" for v in np.asarray(values, np.float64).ravel())
    return f"{name} {mean_pct(values):.1f} % (seeds: {per_seed})"


def missing(claim: str, needed: Sequence[str], have: Mapping[str, Any]) -> Finding | None:
    """A 'not evaluated' finding when any of `needed` is absent from `have`, else None."""
    absent = [n for n in needed if n not in have]
    return Finding(claim, None, f"needs {', '.join(absent)}, not run") if absent else None


def at_least(
    claim: str, a: tuple[str, Any], b: tuple[str, Any], margin_pp: float = 0.0, strict: bool = False
) -> Finding:
    """Holds when mean(a) >= mean(b) + margin_pp (percentage points); > with `strict`."""
    (na, va), (nb, vb) = a, b
    diff = mean_pct(va) - mean_pct(vb)
    rule = f"mean difference {diff:+.1f} pp" + (
        f" (rule: {'>' if strict else '>='} {margin_pp:+.1f} pp)" if margin_pp or strict else ""
    )
    return Finding(
        claim,
        bool(diff > margin_pp if strict else diff >= margin_pp),
        f"{describe(na, va)} vs {describe(nb, vb)}; {rule}",
    )


def below(claim: str, a: tuple[str, Any], b: tuple[str, Any]) -> Finding:
    """Holds when mean(a) < mean(b): `at_least` with the roles swapped, evidence in the claim's order."""
    (na, va), (nb, vb) = a, b
    diff = mean_pct(va) - mean_pct(vb)
    return Finding(
        claim, bool(diff < 0), f"{describe(na, va)} vs {describe(nb, vb)}; mean difference {diff:+.1f} pp (rule: < 0)"
    )


def count(findings: Sequence[Finding]) -> tuple[int, int]:
    """(claims reproduced, claims counted): only verdicts whose evidence carries them."""
    return sum(f.holds is True and f.counted for f in findings), sum(f.counted for f in findings)


def why_not_evidence(name: str, values, collapsed_seeds: Sequence[int | None], base: Mapping[str, Any] | None) -> str:
    """Why row `name` (per-seed accuracies `values` in [0, 1], each seed's `collapsed` class) cannot
    carry a claim: '' where it can, else that a seed collapsed or that its mean is at or below the
    `majority` baseline `base`."""
    hit = sum(k is not None for k in collapsed_seeds)
    if hit:
        return f"{name} collapsed on {hit} of {len(collapsed_seeds)} seeds"
    if base is not None and mean_pct(values) <= base["accuracy"]:
        return f"{name} {mean_pct(values):.1f} % is not above its majority class {base['accuracy']:.1f} %"
    return ""


def counted_where(
    finding: Finding,
    rows: Sequence[tuple[str, Any, Sequence[int | None], Mapping[str, Any] | None]],
    variant: bool = False,
) -> Finding:
    """`finding`, not counted where a row it compares cannot carry it (`rows`: (name, per-seed
    accuracies, per-seed collapsed class, majority baseline) each, `why_not_evidence`) or where it
    is a claim about our `variant` row rather than the paper's."""
    if finding.holds is None:
        return finding
    reasons = (["a claim about our variant row, reported beside the paper's"] if variant else []) + [
        why for row in rows if (why := why_not_evidence(*row))
    ]
    return dataclasses.replace(finding, not_counted="; ".join(reasons))


@dataclasses.dataclass(frozen=True)
class Evidence:
    """What a table's claims read: per-seed accuracies by row (`values`, in [0, 1]; rows not run are
    absent), the split's `majority` baseline, the data's class count, each row's per-seed collapsed
    class (`collapsed`), the study's statistical tests and how the evidence names a row (`plain`)."""

    values: Mapping[str, Any]
    majority: Mapping[str, Any] | None
    n_classes: int
    collapsed: Mapping[str, Sequence[int | None]]
    tests: Mapping[str, Any] | None
    plain: Callable[[str], str]

    def named(self, row: str) -> str:
        """Row `row` as a claim's evidence names it, flagged where its seeds collapsed."""
        return self.plain(row) + collapse_text(self.collapsed.get(row, []))

    def of(self, row: str) -> tuple[str, Any]:
        """(its name, its per-seed accuracies): a side of `at_least`."""
        return self.named(row), self.values[row]


# A claim's rule: its verdict from the evidence, and the rows that verdict compared (which decide
# whether it is counted, `counted_where`).
Rule = Callable[["Claim", Evidence], tuple[Finding, Sequence[str]]]


@dataclasses.dataclass(frozen=True)
class Claim:
    """One of the paper's claims about a table, as data: its words (with the rule they state), the
    rows it needs (not evaluated where any was not run), its `rule` and whether it is about our
    `variant` row rather than the paper's (reported, never counted)."""

    claim: str
    rows: tuple[str, ...]
    rule: Rule
    variant: bool = False


def above(first: str, second: str, margin_pp: float = 0.0, strict: bool = False) -> Rule:
    """The rule "row `first` is at least `margin_pp` above row `second`" (`at_least`), comparing the claim's rows."""
    return lambda c, e: (at_least(c.claim, e.of(first), e.of(second), margin_pp, strict), c.rows)


def evaluate(claims: Sequence[Claim], evidence: Evidence) -> list[Finding]:
    """Every claim of a table checked on `evidence`: not evaluated where a row it needs is missing,
    else its rule's verdict, counted only where the rows it compared can carry it (`counted_where`)."""
    out = []
    for c in claims:
        f = missing(c.claim, c.rows, evidence.values)
        if f is None:
            f, compared = c.rule(c, evidence)
            rows = [
                (evidence.plain(r), evidence.values[r], evidence.collapsed.get(r, []), evidence.majority)
                for r in compared
                if r in evidence.values
            ]
            f = counted_where(f, rows, c.variant)
        out.append(f)
    return out


def markdown(findings: Sequence[Finding | Mapping[str, Any]], counted: bool = True) -> str:
    """A table: claim, verdict, evidence (findings as objects or as their JSON), under the count of
    claims reproduced, or (not `counted`: an install check) the note that none is counted."""
    findings = [f if isinstance(f, Finding) else Finding.from_json(f) for f in findings]
    rows = [
        [
            f.claim,
            f"**{f.verdict}**" if f.holds and f.counted else f.verdict,
            f.evidence + (f". Not counted: {f.not_counted}" if f.not_counted else ""),
        ]
        for f in findings
    ]
    n_true, n_counted = count(findings)
    skipped = sum(f.holds is not None and not f.counted for f in findings)
    tally = (
        f"{n_true} of {n_counted} counted claims reproduced"
        + (f"; {skipped} evaluated but not counted, as their evidence cannot carry them (below)." if skipped else ".")
        if counted
        else NOT_COUNTED
    )
    return f"{tally}\n\n" + results_files.markdown_table(["Paper's claim", "Ours", "Evidence (per-seed results)"], rows)


def claims_markdown(doc: dict[str, Any], claims: str = "the paper's claims about this table") -> list[str]:
    """A table's closing section: the paper's `claims` checked (`doc["findings"]`), or on recorded
    data, which has no paper to check, the note that its rows are compared with each other."""
    if documents.recorded(doc):
        return [documents.RECORDED_NOTE, ""]
    return [
        f"## Findings checklist ({claims})",
        "",
        markdown(doc["findings"], counted=not documents.counts_no_claims(doc)),
    ]


# A model "collapsed" when it predicts one class (or level) for at least this share of the
# sequences of a split whose label is known: its accuracy is then the share of that class, which
# says nothing of what the inputs carry.
COLLAPSED_SHARE = 0.95


def majority(labels) -> dict[str, Any] | None:
    """The strongest trivial baseline of a split: always answering its most frequent known label
    (`labels` below 0 are unknown and ignored; on a tie the lowest label). {"label": that label,
    "accuracy": the percent of known labels it gets right, "known": how many labels are known};
    None when none is known. Computed from the split's own labels, because its classes or levels
    are rarely balanced: 1 / classes is then a lower bar than answering one class already clears."""
    known = np.asarray(labels).ravel()
    known = known[known >= 0]
    if known.size == 0:
        return None
    counts = np.bincount(known)
    label = int(np.argmax(counts))
    return {"label": label, "accuracy": 100.0 * float(counts[label]) / known.size, "known": int(known.size)}


def majority_cell(base: Mapping[str, Any] | None, noun: str = "class") -> str:
    """A table's cell of a `majority` baseline: '60.64 (level 1)', or '–' without known labels."""
    return "–" if base is None else f"{base['accuracy']:.2f} ({noun} {base['label']})"


def collapsed(predictions, labels=None) -> list[int | None]:
    """Per seed (rows of `predictions`: seeds x sequences; one row for a single model), the class it
    predicts for at least `COLLAPSED_SHARE` of the sequences (those whose `labels` are known, where
    given), else None."""
    out = []
    known = None if labels is None else np.asarray(labels).ravel() >= 0
    for p in np.atleast_2d(np.asarray(predictions)):
        p = p if known is None or p.size == 0 else p[known]
        classes, counts = np.unique(p, return_counts=True)
        out.append(int(classes[np.argmax(counts)]) if p.size and counts.max() >= COLLAPSED_SHARE * p.size else None)
    return out


def collapse_text(per_seed: Sequence[int | None], noun: str = "class") -> str:
    """' (collapsed to class k: n of m seeds)' beside an accuracy (`noun`: "level" for a property
    head), or '' when no seed collapsed, from the per-seed result of `collapsed` as a results JSON
    stores it."""
    hit = [k for k in per_seed if k is not None]
    if not hit:
        return ""
    classes = ", ".join(str(k) for k in sorted(set(hit)))
    seeds = f": {len(hit)} of {len(per_seed)} seeds" if len(per_seed) > 1 else ""
    return f" (collapsed to {noun} {classes}{seeds})"


def baseline_note(noun: str = "class") -> str:
    """The sentence under a table with `majority` columns and `collapse_text` flags (`noun`:
    "level" for property heads)."""
    return (
        f"Majority {noun}: the accuracy of always answering the split's most frequent {noun}, from its "
        f"labels (the {noun} in "
        f"brackets), the strongest trivial baseline; *collapsed to {noun} k*: a seed answered k for at least "
        f"{100 * COLLAPSED_SHARE:.0f} % of the split's sequences."
    )


def above_majority(values, base: Mapping[str, Any] | None) -> bool | None:
    """Whether the mean over seeds of `values` (accuracies in [0, 1]) is above the `majority`
    baseline `base` (None without known labels): how every "above chance" claim is counted."""
    return None if base is None else mean_pct(values) > base["accuracy"]


NOT_COUNTED = (
    "Not counted: these results are not the paper's table (the note at the top says what they are); the paper's "
    "checks run, none is counted."
)
