"""The studies' results as types: what a study measured, as its page reads it.

A study measures into one of these and writes it as the study's own part of its results JSON
(`to_json`, beside the header every results file shares); its page and figures read it back from
that JSON alone (`from_json`), so that they can be drawn again without measuring anything. The
JSON is the published format: `to_json` writes exactly the fields, in the order, that the
published files hold.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping, Sequence

import numpy as np

# the fields of an ablation row that are the row's own; the rest are its trained models' (`TrainedRow.doc`)
_ROW_FIELDS = (
    "name",
    "backbone",
    "modalities",
    "display_name",
    "fusion_norm",
    "paper_mean",
    "paper_sd",
    "fusion_choice",
    "probe",
    "collapsed",
)


@dataclasses.dataclass(frozen=True)
class AblationRow:
    """One row of the modality ablation as measured: its inputs and backbone, how the table names
    it, the fusion it is reported under, the paper's test accuracy for it (mean, SD; None on
    recorded data), the class each seed collapsed to per split, and what training it gave
    (`trained`: `TrainedRow.doc`, its per-seed accuracies among them). On recorded data also both
    fusions' accuracies (`fusion_choice`) and the linear probe of its inputs (`probe`)."""

    name: str
    backbone: str
    modalities: tuple[str, ...]
    display_name: str
    fusion_norm: str
    collapsed: Mapping[str, Sequence[int | None]]
    trained: Mapping[str, Any]
    paper: tuple[float, float] | None = None
    fusion_choice: Mapping[str, Any] | None = None
    probe: Mapping[str, Any] | None = None

    @property
    def seeds(self) -> list[int]:
        return list(self.trained["seeds"])

    @property
    def wall_s(self) -> float:
        return self.trained["wall_s"]

    def accuracy(self, split: str = "test", head: str = "fabric") -> np.ndarray:
        """Per-seed accuracy in [0, 1] on `split`."""
        return np.asarray(self.trained["accuracy"][split][head], np.float64)

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "name": self.name,
            "backbone": self.backbone,
            "modalities": list(self.modalities),
            "display_name": self.display_name,
            "fusion_norm": self.fusion_norm,
        }
        if self.paper is not None:
            out["paper_mean"], out["paper_sd"] = self.paper
        if self.fusion_choice is not None:
            out["fusion_choice"] = self.fusion_choice
        if self.probe is not None:
            out["probe"] = self.probe
        return {**out, "collapsed": self.collapsed, **self.trained}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> AblationRow:
        paper = (doc["paper_mean"], doc["paper_sd"]) if "paper_mean" in doc else None
        return cls(
            doc["name"],
            doc["backbone"],
            tuple(doc["modalities"]),
            doc["display_name"],
            doc["fusion_norm"],
            doc["collapsed"],
            {k: v for k, v in doc.items() if k not in _ROW_FIELDS},
            paper,
            doc.get("fusion_choice"),
            doc.get("probe"),
        )


@dataclasses.dataclass(frozen=True)
class Steadiness:
    """Recorded data: each input's within-sequence share of its variance, the share below which it
    counts as steady, and the data's names for its streams."""

    names: Mapping[str, str]
    steady_below: float
    shares: Mapping[str, float]


@dataclasses.dataclass(frozen=True)
class Ablation:
    """What the modality ablation measured: its rows, the test split's majority class, the Wilcoxon
    tests of its pair (None where a row of it did not run), the confusion counts it draws, every
    trained row's time-to-accuracy curve, and either the fusion validation picks for each row
    trained under both (simulated data) or each input's steadiness (recorded data)."""

    rows: tuple[AblationRow, ...]
    majority: Mapping[str, Any] | None
    wilcoxon: Mapping[str, Any] | None
    confusion: Mapping[str, Any]
    time_to_accuracy: tuple[Mapping[str, Any], ...]
    fusion_choice: tuple[Mapping[str, Any], ...] | None = None
    steadiness: Steadiness | None = None

    def test_accuracies(self) -> dict[str, np.ndarray]:
        """Row name -> per-seed test accuracy in [0, 1]: what the paper's claims read."""
        return {r.name: r.accuracy("test") for r in self.rows}

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"rows": [r.to_json() for r in self.rows]}
        if self.fusion_choice is not None:
            out["fusion_choice"] = list(self.fusion_choice)
        if self.steadiness is not None:
            s = self.steadiness
            out.update(names=dict(s.names), steady_below=s.steady_below, steadiness=s.shares)
        return {
            **out,
            "majority": {"test": self.majority},
            "wilcoxon": self.wilcoxon,
            "confusion": self.confusion,
            "time_to_accuracy": list(self.time_to_accuracy),
        }

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Ablation:
        steadiness = Steadiness(doc["names"], doc["steady_below"], doc["steadiness"]) if "steadiness" in doc else None
        fusion_choice = tuple(doc["fusion_choice"]) if "fusion_choice" in doc else None
        return cls(
            tuple(AblationRow.from_json(r) for r in doc["rows"]),
            doc["majority"]["test"],
            doc["wilcoxon"],
            doc["confusion"],
            tuple(doc["time_to_accuracy"]),
            fusion_choice,
            steadiness,
        )


@dataclasses.dataclass(frozen=True)
class Probe:
    """What the linear probe measured: how it reads the inputs (`method`), the splits it fits and
    scores on, the training split's classes, each input's reduction by name (`inputs`) and each
    probe row (its inputs, chosen C, accuracy per split and collapsed classes)."""

    method: Mapping[str, Any]
    splits: tuple[str, ...]
    classes: tuple[int, ...]
    inputs: Mapping[str, Mapping[str, Any]]
    rows: tuple[Mapping[str, Any], ...]

    def to_json(self) -> dict[str, Any]:
        return {
            "method": dict(self.method),
            "splits": list(self.splits),
            "classes": list(self.classes),
            "inputs": dict(self.inputs),
            "rows": list(self.rows),
        }

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Probe:
        return cls(doc["method"], tuple(doc["splits"]), tuple(doc["classes"]), doc["inputs"], tuple(doc["rows"]))
