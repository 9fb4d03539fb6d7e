"""Training curves: per-seed, per-epoch scalars, written as TensorBoard event files.

The jitted epoch scan emits, per seed and epoch, the training loss, the training and validation
accuracy per head and the learning rate (`trainer.Trainer.run`); the host adds each epoch's wall
time. Here they get their TensorBoard names (`tags`), are gathered over a run (`History`) and
written with one `tensorboardX` writer per seed (`open_writer`), in `<log dir>/seed<k>`, so that
TensorBoard overlays the seeds of a row:

    tensorboard --logdir workspace/logs

The step of a scalar is the epoch, counted from 1. tensorboardX is an optional extra
(`pip install -e ".[logs]"`): without it the process logs one line saying so (once, however many
rows it trains) and trains without curves,
because the curves are for watching a run, and the results (`TrainedSeeds.metrics["epochs"]`, the
studies' JSON) carry the same numbers anyway. `read_scalars` reads event files back (tests, and
anyone comparing runs without TensorBoard).
"""

from __future__ import annotations

import os
import struct
import time
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
    """A run's curves as {tag: float32 (seeds, epochs)}, filled chunk by chunk; a resumed run takes
    the epochs before its checkpoint from the checkpoint (`restore`), NaN where the checkpoint has none."""

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

    def to_json(self) -> dict[str, list]:
        """The curves so far, as JSON (null for an epoch not trained yet): saved with a checkpoint,
        so that a resumed run reports the epochs its killed predecessor trained."""
        return {tag: [[None if np.isnan(x) else float(x) for x in row] for row in a] for tag, a in self.scalars.items()}

    def restore(self, saved: Mapping[str, list]) -> None:
        """Take the curves of `to_json` (a checkpoint's), whose epochs this run will not train."""
        for tag, rows in saved.items():
            self.scalars[tag] = np.array(
                [[np.nan if x is None else x for x in row] for row in rows], np.float32
            ).reshape(self.shape)


class CurveWriter:
    """One event file per seed, written synchronously.

    tensorboardX's `SummaryWriter` queues events for a background thread, and its `flush()` does
    not wait for that queue: what a crash or Ctrl-C (a checkpointed run's normal end) leaves on
    disk would be unknown. Its `EventsWriter` writes and flushes in the caller."""

    def __init__(self, log_dir: str | os.PathLike, seeds: Sequence[int], first_epoch: int):
        from tensorboardX.event_file_writer import EventsWriter

        self.writers = []
        for seed in seeds:
            folder = seed_dir(log_dir, seed)
            folder.mkdir(parents=True, exist_ok=True)
            if first_epoch == 0:  # a run from scratch replaces the row's old curves; a resumed run adds a file
                for old in folder.glob("events.out.tfevents.*"):
                    old.unlink()
            # event files are named by the second they were opened in: the suffix keeps a resume
            # within the same second from overwriting the interrupted run's file
            self.writers.append(EventsWriter(str(folder / "events"), f".from_epoch{first_epoch + 1}"))

    def write(self, history: History, start: int, stop: int) -> None:
        """Epochs `start` .. `stop` - 1 of `history`, on disk when this returns."""
        from tensorboardX.proto.event_pb2 import Event
        from tensorboardX.summary import scalar

        now = time.time()
        for i, w in enumerate(self.writers):
            for e in range(start, stop):
                for tag, values in history.scalars.items():
                    w.write_event(Event(wall_time=now, step=e + 1, summary=scalar(tag, values[i, e])))
            w.flush()

    def close(self) -> None:
        for w in self.writers:
            w.close()


_said_curves_are_off = False  # whether this process has logged that tensorboardX is missing


def open_writer(log_dir: str | os.PathLike, seeds: Sequence[int], first_epoch: int) -> CurveWriter | None:
    """A writer per seed under `log_dir` for a run starting at `first_epoch` (0-based), or None
    when tensorboardX is not installed: then one log line says so, once per process, not once per
    row of a study."""
    global _said_curves_are_off
    try:
        return CurveWriter(log_dir, seeds, first_epoch)
    except ImportError:
        if not _said_curves_are_off:
            logging.warning("training curves are off: tensorboardX is not installed (%s)", EXTRA)
            _said_curves_are_off = True
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
