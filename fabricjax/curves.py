"""Training curves: per-seed, per-epoch scalars, written as TensorBoard event files.

The jitted epoch scan emits, per seed and epoch, the training loss, the training and validation
accuracy per head and the learning rate (`train.Trainer.run`); the host adds each epoch's wall
time. Here they get their TensorBoard names (`tags`), are gathered over a run (`History`) and
written with one `tensorboardX` writer per seed (`open_writer`), in `<log dir>/seed<k>`, so that
TensorBoard overlays the seeds of a row:

    tensorboard --logdir workspace/logs

The step of a scalar is the epoch, counted from 1. tensorboardX is an optional extra
(`pip install -e ".[logs]"`): without it a run logs one line saying so and trains without curves,
because the curves are for watching a run, and the results (`Results.metrics["epochs"]`, the
studies' JSON) carry the same numbers anyway. `read_scalars` reads event files back (tests, and
anyone comparing runs without TensorBoard).
"""

from __future__ import annotations

import os
import struct
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from absl import logging

EXTRA = 'pip install -e ".[logs]"'
WALL_TAG = "epoch_wall_s"


def tags(summary: Mapping[str, Any]) -> dict[str, Any]:
    """The epoch scan's summary ({"train_loss", "train_accuracy": {head}, "val_accuracy": {head},
    "lr"}, any leading axes) by TensorBoard tag."""
    return {
        "train/loss": summary["train_loss"],
        **{f"train/accuracy/{h}": v for h, v in summary["train_accuracy"].items()},
        **{f"val/accuracy/{h}": v for h, v in summary["val_accuracy"].items()},
        "lr": summary["lr"],
    }


def seed_dir(log_dir: str | os.PathLike, seed: int) -> Path:
    return Path(log_dir) / f"seed{seed}"


class History:
    """A run's curves as {tag: float32 (seeds, epochs)}, filled chunk by chunk; NaN where an epoch
    was trained by an earlier, interrupted process (a resumed run starts from its checkpoint)."""

    def __init__(self, n_seeds: int, n_epochs: int):
        self.shape = (n_seeds, n_epochs)
        self.scalars: dict[str, np.ndarray] = {}

    def add(self, first_epoch: int, summary: Mapping[str, Any], wall_s: float) -> None:
        """The summary of epochs `first_epoch`, ... (arrays (seeds, n)), each of which took `wall_s`."""
        chunk = tags(summary)
        n = np.shape(chunk["lr"])[1]
        chunk[WALL_TAG] = np.full((self.shape[0], n), wall_s)
        for tag, values in chunk.items():
            full = self.scalars.setdefault(tag, np.full(self.shape, np.nan, np.float32))
            full[:, first_epoch : first_epoch + n] = values


class CurveWriter:
    """One tensorboardX `SummaryWriter` per seed."""

    def __init__(self, log_dir: str | os.PathLike, seeds: Sequence[int], fresh: bool):
        from tensorboardX import SummaryWriter

        self.writers = []
        for seed in seeds:
            folder = seed_dir(log_dir, seed)
            if fresh:  # a run from scratch replaces the row's old curves; a resumed run appends
                for old in folder.glob("events.out.tfevents.*"):
                    old.unlink()
            self.writers.append(SummaryWriter(str(folder)))

    def write(self, history: History, start: int, stop: int) -> None:
        """Epochs `start` .. `stop` - 1 of `history`, flushed so that TensorBoard shows them now."""
        for i, w in enumerate(self.writers):
            for tag, values in history.scalars.items():
                for e in range(start, stop):
                    w.add_scalar(tag, float(values[i, e]), global_step=e + 1)
            w.flush()

    def close(self) -> None:
        for w in self.writers:
            w.close()


def open_writer(log_dir: str | os.PathLike, seeds: Sequence[int], fresh: bool) -> CurveWriter | None:
    """A writer per seed under `log_dir`, or None (one log line) when tensorboardX is not installed."""
    try:
        return CurveWriter(log_dir, seeds, fresh)
    except ImportError:
        logging.warning("training curves are off: tensorboardX is not installed (%s)", EXTRA)
        return None


def read_scalars(folder: str | os.PathLike) -> dict[str, dict[int, float]]:
    """{tag: {step: value}} of every event file in `folder` (a seed's folder), later files winning.

    Event files are TFRecord files (length, CRC, serialized `Event`, CRC) of tensorboardX's
    bundled protobuf messages; CRCs are not checked."""
    from tensorboardX.proto import event_pb2

    out: dict[str, dict[int, float]] = {}
    for path in sorted(Path(folder).glob("events.out.tfevents.*")):
        data = path.read_bytes()
        pos = 0
        while pos + 12 <= len(data):
            (length,) = struct.unpack("<Q", data[pos : pos + 8])
            event = event_pb2.Event.FromString(data[pos + 12 : pos + 12 + length])
            pos += 12 + length + 4
            for v in event.summary.value:
                out.setdefault(v.tag, {})[int(event.step)] = float(v.simple_value)
    return out
