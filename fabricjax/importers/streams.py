"""A recording as the importers hold it before alignment: each microphone a `Stream` of SPH0645-style
words (`to_words`) with the times it held them, and `RecordingImportError`, the one-line error of a
recording that cannot become a trial archive."""

from __future__ import annotations

import dataclasses

import numpy as np

from fabricjax.errors import UserError


class RecordingImportError(UserError):
    """A recording cannot become an archive; the message names file, field and problem."""

    def __init__(self, path, field: str, problem: str):
        self.path, self.field, self.problem = str(path), field, problem
        super().__init__(f"{path}: {field}: {problem}")

    def __reduce__(self):
        # rebuilt from its three parts, so a worker process can raise it to the parent (the
        # default, cls(message), would fail to unpickle and break the pool)
        return type(self), (self.path, self.field, self.problem)


@dataclasses.dataclass
class Stream:
    """One microphone as recorded: its samples, and the times (s) at which it held `counts` of them
    (a bag: each message's receive time and the samples up to its end; a WAV file: every sample's time)."""

    name: str  # topic or file, for errors
    rate: int
    samples: np.ndarray  # (S,) int32 SPH0645-style words
    times: np.ndarray  # (K,) float64, increasing
    counts: np.ndarray  # (K,) int64, samples held at each time
    truncated: bool = False  # the file ends before the length its header declares (a cut-off recording)
    recorded_as: str | None = None  # what the file held before `to_words`, e.g. "16-bit PCM WAV" (None: SPH0645 words)

    @classmethod
    def from_chunks(cls, name: str, rate: int, times, chunks: list[np.ndarray]) -> "Stream":
        """Messages in any order, each a chunk of samples stamped with its last sample's time."""
        if not chunks:
            raise RecordingImportError(name, "audio", "no messages")
        order = np.argsort(np.asarray(times, np.float64), kind="stable")
        ordered = [chunks[i] for i in order]
        counts = np.cumsum([len(c) for c in ordered]).astype(np.int64)
        return cls(name, rate, np.concatenate(ordered), np.asarray(times, np.float64)[order], counts)

    @classmethod
    def from_samples(
        cls,
        name: str,
        rate: int,
        samples: np.ndarray,
        start: float = 0.0,
        truncated: bool = False,
        recorded_as: str | None = None,
    ) -> "Stream":
        """A continuous recording (a WAV file) whose first sample is at `start`."""
        if len(samples) == 0:
            raise RecordingImportError(name, "audio", "no samples")
        return cls(
            name,
            rate,
            samples,
            start + np.arange(len(samples)) / rate,
            np.arange(1, len(samples) + 1, dtype=np.int64),
            truncated,
            recorded_as,
        )


def recorded_as(samples: np.ndarray, container: str) -> str:
    """What a file's samples were before `to_words`: "16-bit PCM WAV" for int16, "32-bit PCM WAV
    (read as SPH0645 words)" for int32."""
    if samples.dtype == np.int16:
        return f"16-bit PCM {container}, placed in the top 16 of the 18 valid bits"
    return f"{8 * samples.dtype.itemsize}-bit PCM {container}, read as SPH0645 words"


def to_words(samples: np.ndarray, where, field: str) -> np.ndarray:
    """int16 samples move to the top 16 of the 18 valid SPH0645 bits; int32 words are kept as they are."""
    if samples.dtype == np.int16:
        return samples.astype(np.int32) << 16
    if samples.dtype == np.int32:
        return samples
    raise RecordingImportError(where, field, f"audio samples must be int16 or int32, got {samples.dtype}")
