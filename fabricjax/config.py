"""One experiment's configuration: which data, which features, which model, how to train.

Configs are code: experiments build them with `Config(...)` / `dataclasses.replace` and every
field is overridable from absl flags. A config is hashable and JSON-serialisable (`to_json`),
which is how checkpoints and caches recognise the config they were made with.
"""

from __future__ import annotations

import dataclasses
import json
from typing import Any

from fabricjax import splits

# Input streams by name. "internal"/"external" are the Minsound / palm microphone PSDs (one shared
# encoder), "proprio" the 18 joint values, "flow" the patch-pooled optical flow, "image" Minsight
# frames (downsampled to `image_size` or at the archive's resolution, see `image_resolution`).
MODALITIES = ("image", "flow", "internal", "external", "proprio")
AUDIO_MODALITIES = ("internal", "external")
# How tables and figures name each modality (the sensors of the paper).
MODALITY_NAMES = {"image": "Minsight image", "flow": "optical flow", "internal": "Minsound", "external": "palm mic", "proprio": "proprioception"}
BACKBONES = ("attention", "tcn")
BANDWIDTHS_KHZ = (2.5, 10.0, 15.0, 24.0)
# How the concatenated per-step features are normalised before the backbone: the paper's rescale of
# each dimension to [0, 1] over the sequence, or our variant, a LayerNorm over each step's features
# (keeps each feature's steady level, which the rescale discards).
FUSION_NORMS = ("sequence_minmax", "step_layernorm")
LR_SCHEDULES = ("constant", "cosine")


@dataclasses.dataclass(frozen=True)
class Config:
    preset: str = "default"
    modalities: tuple[str, ...] = ("internal",)
    backbone: str = "attention"
    seq_len: int | None = None  # None: the preset's N
    bandwidth_khz: float = 15.0
    image_resolution: str = "down"  # "down" = image_size, "full" = the archive's resolution
    image_size: tuple[int, int] = (60, 80)  # the "down" frame size: the paper's 60x80
    # model
    width: int = 64
    n_heads: int = 4
    n_layers: int = 3
    ffn: int = 128
    audio_hidden: tuple[int, int] = (128, 64)
    proprio_hidden: tuple[int, int] = (64, 64)
    cnn_features: tuple[int, ...] = (16, 32, 64)  # image / flow CNN channels per strided conv
    dropout: float = 0.1
    fusion_norm: str = "sequence_minmax"  # FUSION_NORMS; the paper's is the default
    fabric_head: bool = True
    property_heads: bool = False
    compute_dtype: str = "float32"
    # training
    epochs: int = 40
    batch_size: int = 32
    learning_rate: float = 1e-3
    lr_schedule: str = "constant"  # LR_SCHEDULES, after the warm-up
    warmup_steps: int = 100  # linear warm-up from 0: without it a few seeds collapse to chance early
    weight_decay: float = 1e-4
    augment_rotation: bool = True
    # training data selection: fabrics excluded from training (the property holdouts)
    exclude_fabrics: tuple[int, ...] = ()

    def __post_init__(self):
        bad = [m for m in self.modalities if m not in MODALITIES]
        if bad or not self.modalities:
            raise ValueError(f"modalities must be a non-empty subset of {MODALITIES}, got {self.modalities}")
        if self.backbone not in BACKBONES:
            raise ValueError(f"backbone must be one of {BACKBONES}, got {self.backbone!r}")
        if not 0 < self.bandwidth_khz <= 24.0:
            raise ValueError(f"bandwidth_khz must be in (0, 24], got {self.bandwidth_khz}")
        if self.fusion_norm not in FUSION_NORMS:
            raise ValueError(f"fusion_norm must be one of {FUSION_NORMS}, got {self.fusion_norm!r}")
        if self.lr_schedule not in LR_SCHEDULES:
            raise ValueError(f"lr_schedule must be one of {LR_SCHEDULES}, got {self.lr_schedule!r}")
        if self.image_resolution not in ("down", "full"):
            raise ValueError(f"image_resolution must be 'down' or 'full', got {self.image_resolution!r}")
        if not (self.fabric_head or self.property_heads):
            raise ValueError("at least one of fabric_head and property_heads must be on")
        splits.preset(self.preset)  # raises on an unknown preset

    @property
    def sequence_length(self) -> int:
        return self.seq_len or splits.preset(self.preset).seq_len

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> "Config":
        fields = {f.name: f for f in dataclasses.fields(cls)}
        unknown = set(d) - set(fields)
        if unknown:
            raise ValueError(f"unknown config fields {sorted(unknown)}")
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})

    def dumps(self) -> str:
        return json.dumps(self.to_json(), sort_keys=True)
