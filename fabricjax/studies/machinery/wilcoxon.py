"""Row against row: paired Wilcoxon signed-rank tests of two trained rows on one split."""

from __future__ import annotations

import numpy as np

from fabricjax.reporting import stats
from fabricjax.studies.machinery.trained import TrainedRow


def paired_tests(
    a: TrainedRow, b: TrainedRow, split: str, labels: np.ndarray, head: str = "fabric"
) -> dict[str, stats.WilcoxonResult]:
    """Wilcoxon signed-rank tests of row `b` against row `a` on `split`, under both pairings.

    per_seed: accuracy of b and a for the same seed (same key, same data); the exact test over n
    seeds cannot give p below 2 / 2^n.
    per_sample: correctness (0/1) of b and a on the same sequence and seed, pooled over seeds
    (many ties: normal approximation). Sequences of one trial and the seeds' shared data are not
    independent, so this p-value is optimistic; it is reported because it is what a per-sample
    comparison gives, not as the headline.
    """
    if b.results.seeds != a.results.seeds:
        raise ValueError(f"rows {a.name} and {b.name} were trained with different seeds")
    n = len(a.results.seeds)
    valid = np.asarray(labels) >= 0
    correct = lambda r: (r.predictions(split, head) == labels)[:, valid].astype(np.float64)  # noqa: E731
    return {
        "per_seed": stats.wilcoxon(
            b.accuracy(split, head),
            a.accuracy(split, head),
            pairing=f"per seed: {split} accuracy of the same seed, {n} seeds",
        ),
        "per_sample": stats.wilcoxon(
            correct(b),
            correct(a),
            pairing=f"per {split} sequence: correctness (0/1) on the same sequence and seed, pooled over {n} seeds",
        ),
    }
