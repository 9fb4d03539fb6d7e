"""What a trained row costs to run and what a touch lasts: a model's size and single-sequence
inference latency, and the data's step rate that turns N steps into touch time.

The cost study and the recipe sweep time their rows with it; the decision study reads the step
rate to turn a stopping rule's steps into seconds.
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np

from fabricjax import timing
from fabricjax.reporting import stats
from fabricjax.sequences import data
from fabricjax.store import archive, dataset_index
from fabricjax.studies.machinery.trained import TrainedRow


def inference_latency(
    graphdef, params, inputs: dict[str, np.ndarray], repeats: int, warmup: int = 5
) -> dict[str, float]:
    """p50 / p99 ms of `predict_one` compiled ahead of time on one sequence, result fetched to the
    host (`timing.predict_one_timer`)."""
    run = timing.predict_one_timer(graphdef, params, inputs, warmup=warmup)
    return {f"latency_{k}": v for k, v in stats.percentiles_ms([run() for _ in range(repeats)]).items()}


def measure_inference(row: TrainedRow, test: data.SequenceSet, repeats: int) -> dict[str, Any]:
    """A trained row's size and inference latency: the parameter count of its first seed's model
    and `inference_latency` on the first sequence of `test` (loaded for several rows: narrowed
    to the row's inputs here)."""
    params = row.results.params(0)
    mine = data.narrow({"test": test}, row.config)["test"]
    return {
        "params": int(sum(np.size(x) for x in jax.tree.leaves(params))),
        **inference_latency(row.results.graphdef, params, {m: a[0] for m, a in mine.inputs.items()}, repeats),
    }


def steps_and_rate(folder, workdir=None) -> tuple[int, float]:
    """The shortest trial's steps and the data's step rate [Hz] (50 on the hand; a rig's own):
    touch time is N steps at it, so trials stepping at different rates have none."""
    entries = dataset_index.load_index(folder, workdir).entries
    rates = sorted({archive.layout(e.meta).step_rate for e in entries})
    if len(rates) > 1:
        raise archive.ArchiveError(
            folder, "meta.streams.steps.rate", f"the trials step at {rates} Hz: touch time needs one step rate"
        )
    return min(e.n_steps - data.first_step(e.meta) for e in entries), rates[0]
