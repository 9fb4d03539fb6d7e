"""One experiment's configuration: which data, which features, which model, how to train.

Configs are code. `Config()`'s defaults are the paper's (its dataset preset, N=200, its model and
training). A preset reaches a config one way, its `preset` field: `Config(preset=name, **fields)`
(or `Config.from_preset(name, **fields)`) is the named preset (`presets.py`), its dataset and its
training fields, with `fields` on top. Every field is overridable from the command line as `--set field=value`,
typed and checked against the field's annotation (`parse_override`). A config is hashable and
JSON-serialisable (`to_json`), which is how checkpoints and caches recognise the config they were
made with.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import typing
from typing import Any

from fabricjax import catalog, presets
from fabricjax.errors import UserError
from fabricjax.store import archive

# Input streams by name. "internal"/"external" are the Minsound / palm microphone PSDs (one shared
# encoder), "proprio" the joint values (`archive.N_PROPRIO`), "flow" the patch-pooled optical
# flow, "image" Minsight frames (downsampled to `image_size` or at the archive's resolution, see
# `image_resolution`).
MODALITIES = ("image", "flow", "internal", "external", "proprio")
CAMERA_MODALITIES = archive.CAMERA_MODALITIES
AUDIO_MODALITIES = archive.MIC_NAMES  # a microphone's PSD is the modality of the same name
# How tables and figures name each modality (the sensors of the paper).
MODALITY_NAMES = {
    "image": "Minsight image",
    "flow": "optical flow",
    "internal": "Minsound",
    "external": "palm mic",
    "proprio": "proprioception",
}
BACKBONES = ("attention", "tcn")
IMAGE_RESOLUTIONS = ("down", "full")  # `Config.image_size`, or the archive's own frame size
PAPER_WINDOW_S = archive.WINDOW / archive.AUDIO_RATE  # the paper's step window: 2048 samples at 48 kHz, 42.67 ms
# How the concatenated per-step features are normalised before the backbone: the paper's rescale of
# each dimension to [0, 1] over the sequence, or our variant, a LayerNorm over each step's features
# (keeps each feature's steady level, which the rescale discards).
FUSION_NORMS = ("sequence_minmax", "step_layernorm")
# How the image and flow CNNs (`model.ConvEncoder`) turn their last layer's grid of cells into one
# step's features: the mean over the cells (translation-invariant), or every cell's features side by
# side, which keeps where on the imaged wall a response sits. The paper does not say; each CNN's
# default is the one its rows learn best with on validation (docs/usage.md, "What the camera rows
# learn"): the grid for the Minsight image, the mean for optical flow.
CNN_POOLS = ("mean", "grid")
LR_SCHEDULES = ("constant", "cosine")
# The nonlinearity between the classification head's two linear layers, which the paper does not name:
# ReLU, or GELU, whose negative side keeps a gradient. The head reads each sequence's mean latent, which
# under the paper's [0, 1] rescale varies little between sequences, so a ReLU unit is often off for
# every sequence at once, and once all of them are the head answers the class prior for good.
HEAD_ACTIVATIONS = ("relu", "gelu")
# The two readings of the paper's flow filter, "filter for the top 0.1 percentile according to
# magnitude" (fabricjax/features/flow.py): keep the strongest 0.1 % of vectors, or drop them.
FLOW_SPARSIFY = ("keep_top", "drop_top")
# Who computes the dense Farneback flow (fabricjax/features/flow.py): OpenCV on the host (the
# default and the reference), or its JAX reimplementation in batches on JAX's devices.
FLOW_METHODS = ("opencv", "jax")
# What the image encoder's input is measured from (model.FabricNet.standardise). Minsight's own force
# network reads each frame minus a no-contact reference (Andrussow et al., "Minsight: A Fingertip-Sized
# Vision-Based Tactile Sensor for Robotic Manipulation", Advanced Intelligent Systems, 2023), which
# removes the LEDs' fixed colour field, so the paper's rotation turns the shell's deformation and not
# the camera's own lighting. "session" (the default) is that reading: each frame minus its own
# session's no-contact reference, which the trial archive carries (format 3, `archive.reference`);
# the LED drive and the shell's seating move between sessions, and only the session's own reference
# follows them. "training_mean" subtracts the training split's mean frame per pixel instead, and
# "none" centres each colour channel on its training mean, as the paper's pipeline reads the frame.
IMAGE_REFERENCES = ("none", "training_mean", "session")
# What the image input's fixed standardisation divides by (`inputs.input_statistics`): one SD per colour
# over every pixel of the training split, or one per pixel and colour (with each pixel's own mean),
# as the linear probe standardises each of its dimensions: the contact patch's few pixels then weigh
# no more than the quiet rest of the wall.
IMAGE_STANDARDISATIONS = ("channel", "pixel")
# How the paper's rotation (features/images.py) samples a turned frame, which the paper does not say:
# bilinear interpolation between the four nearest source pixels, or the nearest source pixel alone
# (which keeps each pixel's value whole instead of blending a contact's few pixels with their
# neighbours).
ROTATION_INTERPOLATIONS = ("bilinear", "nearest")
# What the rotation brings in where a turned frame's source lies outside the frame, also unsaid by the
# paper: the training split's mean input (the standardised input's 0), or the input's own 0 before
# standardisation, which under `image_reference="session"` is the session's no-contact frame.
ROTATION_FILLS = ("mean", "no_contact")
# The dtype of the model's matrix-product and convolution inputs (`model.dense`): products
# accumulate in float32, and parameters, optimiser state, LayerNorms, softmax, the [0, 1] rescale,
# the loss and every statistic stay float32 whatever it is. bfloat16 runs on the bfloat16 dot
# units of CPUs that have them (x86 `avx512_bf16` / AMX, Arm `bf16`); float16 is kept for the
# stability tests' overflow cases.
COMPUTE_DTYPES = ("float32", "bfloat16", "float16")
# Where training reads its inputs (`Config.input_source`).
INPUT_SOURCES = ("auto", "memory", "disk")

# What a `Config` field decides, its metadata's "role". The lists of fields that must agree are derived
# from these roles and two more metadata entries (see `_field`): `RESULT_NEUTRAL_FIELDS`,
# `SEQUENCE_FIELDS` and `RATE_NEUTRAL_FIELDS`.
SEQUENCES = "sequences"  # which trials are loaded and how they are cut into sequences
FEATURES = "features"  # the per-step arrays of the loaded sequences: which inputs, computed how
RESULT = "result"  # the model and its training
NEUTRAL = "nothing"  # no result: a run gives the same bits under any value
ROLES = (SEQUENCES, FEATURES, RESULT, NEUTRAL)
# The fields that take one of a fixed set of values (`Config.__post_init__`), and how an error names
# a set that it does not print as a tuple.
_CHOICES = {
    "backbone": BACKBONES,
    "fusion_norm": FUSION_NORMS,
    "image_pool": CNN_POOLS,
    "flow_pool": CNN_POOLS,
    "lr_schedule": LR_SCHEDULES,
    "head_activation": HEAD_ACTIVATIONS,
    "flow_sparsify": FLOW_SPARSIFY,
    "flow_method": FLOW_METHODS,
    "image_reference": IMAGE_REFERENCES,
    "image_standardisation": IMAGE_STANDARDISATIONS,
    "rotation_interpolation": ROTATION_INTERPOLATIONS,
    "rotation_fill": ROTATION_FILLS,
    "input_source": INPUT_SOURCES,
    "compute_dtype": COMPUTE_DTYPES,
    "image_resolution": IMAGE_RESOLUTIONS,
}
_CHOICES_SAID = {"image_resolution": "'down' or 'full'"}


def _field(default: Any, role: str, *, load: int | None = None, rate_neutral: bool = False) -> Any:
    """A `Config` field with its default and what it decides (`role`, one of `ROLES`). `load`: the
    field's place in the key of a load that several rows share (`SEQUENCE_FIELDS`), for every field
    such rows must agree on; a field that decides the sequences without one is given to each row by
    `data.narrow` from the shared load (modalities, bandwidth). `rate_neutral`: a published row that
    differs in it still gives this row's training seconds per sequence (`RATE_NEUTRAL_FIELDS`)."""
    metadata: dict[str, Any] = {"role": role, "rate_neutral": rate_neutral}
    if load is not None:
        metadata["load"] = load
    return dataclasses.field(default=default, metadata=metadata)


# A count of epochs and the budget in optimiser steps that replaces it on the data loaded
# (`loading.Dataset.config_for`): a count given without its budget sets the budget to 0 (none).
_BUDGETS = (("epochs", "train_steps"), ("patience", "patience_steps"))


def _preset_fields_first(cls):
    """`cls(preset=name, **fields)` takes the fields preset `name` sets (`presets.Preset.training`)
    before its own defaults, with `fields` on top: building a config directly and through
    `from_preset` give the same config. `epochs` (or `patience`) given without `train_steps`
    (`patience_steps`) is trained as given: the preset's budget in steps does not replace it
    (`--set=epochs=4` trains 4 epochs). A config built from all its fields (`dataclasses.replace`,
    `from_json`) is those fields."""
    init = cls.__init__

    @functools.wraps(init)
    def __init__(self, preset: str = "paper", **fields):
        given = dict(fields)
        for count, budget in _BUDGETS:  # an epoch count asked for is trained, not replaced by the preset's step budget
            if count in given and budget not in given:
                given[budget] = 0
        init(self, preset=preset, **{**presets.get(preset).training, **given})

    cls.__init__ = __init__
    return cls


@_preset_fields_first
@dataclasses.dataclass(frozen=True)
class Config:
    # the dataset and training preset (presets.PRESETS)
    preset: str = _field("paper", SEQUENCES, load=0, rate_neutral=True)
    modalities: tuple[str, ...] = _field(("internal",), FEATURES)
    backbone: str = _field("attention", RESULT)
    seq_len: int = _field(200, SEQUENCES, load=1)  # N, steps per sequence: the paper's 4 s at 50 Hz
    bandwidth_khz: float = _field(15.0, FEATURES, rate_neutral=True)
    # each microphone's step window [s] at its own rate (features/welch.py); None: the dataset's own (a rig
    # file's steps.mic_window_s, recorded in the archives), else PAPER_WINDOW_S. A value set here wins over the data's.
    mic_window_s: float | None = _field(None, FEATURES, load=7, rate_neutral=True)
    # IMAGE_RESOLUTIONS: "down" = image_size, "full" = the archive's resolution
    image_resolution: str = _field("down", FEATURES, load=3)
    image_size: tuple[int, int] = _field((60, 80), FEATURES, load=4)  # the "down" frame size: the paper's 60x80
    flow_sparsify: str = _field("keep_top", FEATURES, load=5)  # FLOW_SPARSIFY
    flow_method: str = _field("opencv", FEATURES, load=6)  # FLOW_METHODS
    # model
    width: int = _field(64, RESULT, rate_neutral=True)
    n_heads: int = _field(4, RESULT)
    n_layers: int = _field(3, RESULT)
    ffn: int = _field(128, RESULT)
    audio_hidden: tuple[int, int] = _field((128, 64), RESULT)
    proprio_hidden: tuple[int, int] = _field((64, 64), RESULT)
    cnn_features: tuple[int, ...] = _field((16, 32, 64), RESULT)  # image / flow CNN channels per strided conv
    image_pool: str = _field("grid", RESULT)  # CNN_POOLS
    flow_pool: str = _field("mean", RESULT)  # CNN_POOLS
    dropout: float = _field(0.1, RESULT, rate_neutral=True)
    fusion_norm: str = _field("sequence_minmax", RESULT, rate_neutral=True)  # FUSION_NORMS; the paper's is the default
    head_activation: str = _field("relu", RESULT)  # HEAD_ACTIVATIONS
    fabric_head: bool = _field(True, RESULT)
    # the fabric head's classes: the dataset's label map (studies set it from the data)
    n_classes: int = _field(catalog.N_CLASSES, RESULT, rate_neutral=True)
    property_heads: bool = _field(False, RESULT)
    compute_dtype: str = _field("float32", RESULT)  # COMPUTE_DTYPES
    # training
    # the most epochs a seed trains (with `patience`, the cap of early stopping)
    epochs: int = _field(40, RESULT, rate_neutral=True)
    # early stopping: a seed stops after this many epochs without a better validation accuracy and
    # keeps its best-validation parameters (0: every seed trains all `epochs`, the paper's recipe)
    patience: int = _field(0, RESULT, rate_neutral=True)
    # the training budget and the patience in optimiser steps per seed, whatever the data's size (0:
    # `epochs` and `patience` as given): the data a study loads sets `epochs` and `patience` to the
    # fewest epochs that cover them (`loading.Dataset.config_for`), so a small dataset gets as many
    # updates as a large one instead of as many passes
    train_steps: int = _field(0, RESULT, rate_neutral=True)
    patience_steps: int = _field(0, RESULT, rate_neutral=True)
    # the recipe chosen by validation accuracy (`studies.machinery.recipe`): each learning rate and width of
    # these grids is trained, and a row keeps the best; empty: `learning_rate` and `width` as they are
    lr_grid: tuple[float, ...] = _field((), RESULT, rate_neutral=True)
    width_grid: tuple[int, ...] = _field((), RESULT, rate_neutral=True)
    batch_size: int = _field(32, RESULT)
    learning_rate: float = _field(1e-3, RESULT, rate_neutral=True)
    lr_schedule: str = _field("constant", RESULT, rate_neutral=True)  # LR_SCHEDULES, after the warm-up
    # linear warm-up from 0: the first updates stay small while Adam's moments settle
    warmup_steps: int = _field(100, RESULT, rate_neutral=True)
    weight_decay: float = _field(1e-4, RESULT, rate_neutral=True)
    # the paper's image augmentation (features/images.py), applied to the model's input
    augment_rotation: bool = _field(True, RESULT)
    rotation_interpolation: str = _field("bilinear", RESULT)  # ROTATION_INTERPOLATIONS
    rotation_fill: str = _field("mean", RESULT)  # ROTATION_FILLS
    # IMAGE_REFERENCES; chosen by measurement (docs/usage.md, "Can the model read each input?"). It decides the
    # features ("session" is its own) and the model (the others subtract in `model.FabricNet.standardise`).
    image_reference: str = _field("session", FEATURES, load=8)
    image_standardisation: str = _field("channel", RESULT)  # IMAGE_STANDARDISATIONS
    # training data selection: fabrics excluded from training (the property holdouts)
    exclude_fabrics: tuple[int, ...] = _field((), SEQUENCES, load=2, rate_neutral=True)
    # where training reads its inputs (INPUT_SOURCES): placed whole on the devices ("memory"), or
    # minibatches read from the host (`fabricjax.training.feed`) out of memory-mapped sequence files
    # ("disk", `data.load_sequences`); "auto": from disk where the loaded inputs would take more
    # than `data.MEMORY_FRACTION` of this machine's memory. Either way it is the same computation,
    # the same bits where XLA's fusions are off (tests/test_feed.py); with them, XLA compiles the two
    # programs apart and may round a sum differently.
    input_source: str = _field("auto", NEUTRAL, load=9, rate_neutral=True)

    def __post_init__(self):
        bad = [m for m in self.modalities if m not in MODALITIES]
        if bad or not self.modalities:
            raise ValueError(f"modalities must be a non-empty subset of {MODALITIES}, got {self.modalities}")
        for name, choices in _CHOICES.items():
            value = getattr(self, name)
            if value not in choices:
                raise ValueError(f"{name} must be {_CHOICES_SAID.get(name, f'one of {choices}')}, got {value!r}")
        if not 0 < self.bandwidth_khz <= archive.NYQUIST_KHZ:
            raise ValueError(f"bandwidth_khz must be in (0, {archive.NYQUIST_KHZ:g}], got {self.bandwidth_khz}")
        if self.mic_window_s is not None and not 0 < self.mic_window_s < float("inf"):
            raise ValueError(
                f"mic_window_s must be a duration in seconds > 0 (or none: the data's), got {self.mic_window_s}"
            )
        if not (self.fabric_head or self.property_heads):
            raise ValueError("at least one of fabric_head and property_heads must be on")
        if self.n_classes < 2:
            raise ValueError(f"n_classes must be at least 2, got {self.n_classes}")
        if any(not 0 < lr < 1 for lr in self.lr_grid) or any(w < 1 for w in self.width_grid):
            raise ValueError(
                f"lr_grid holds learning rates in (0, 1) and width_grid widths >= 1, got {self.lr_grid} and "
                f"{self.width_grid}"
            )
        if self.train_steps < 0 or self.patience_steps < 0:
            raise ValueError(
                f"train_steps and patience_steps must be 0 (epochs as given) or numbers of optimiser steps, "
                f"got {self.train_steps}, {self.patience_steps}"
            )
        if self.patience < 0:
            raise ValueError(f"patience must be 0 (no early stopping) or a number of epochs, got {self.patience}")
        for name in ("seq_len", "epochs", "batch_size"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1, got {getattr(self, name)}")

    @classmethod
    def from_preset(cls, name: str, **overrides) -> "Config":
        """`Config(preset=name, **overrides)`: the preset's training fields on `Config`'s defaults,
        with `overrides` on top; the preset itself is chosen by name, not overridden as a field."""
        if "preset" in overrides:
            raise UserError(f"the preset is chosen by name (--preset={overrides['preset']}), not overridden as a field")
        return cls(preset=name, **overrides)

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> "Config":
        fields = {f.name: f for f in dataclasses.fields(cls)}
        unknown = set(d) - set(fields)
        if unknown:
            raise ValueError(f"unknown config fields {sorted(unknown)}")
        d = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}
        # a saved config may hold seq_len null (N unset): read as its preset's N, so such checkpoints still restore
        if "seq_len" in d and d["seq_len"] is None:
            d["seq_len"] = presets.get(d.get("preset", cls.preset)).training.get("seq_len", cls.seq_len)
        return cls(**d)

    def dumps(self) -> str:
        return json.dumps(self.to_json(), sort_keys=True)


_FIELDS = dataclasses.fields(Config)
# Fields that do not change a run's results, so a checkpoint resumes under any of their values
# (`checkpoint.check_meta`).
RESULT_NEUTRAL_FIELDS = tuple(f.name for f in _FIELDS if f.metadata.get("role") == NEUTRAL)
# The fields besides modalities and bandwidth that decide the sequences `data.load_sequences` returns
# (which trials, how they are cut, which features, where they are held), in the order of a load's key
# (`loading.sequence_key`): one load serves several rows only where these agree.
SEQUENCE_FIELDS = tuple(
    f.name for f in sorted((f for f in _FIELDS if "load" in f.metadata), key=lambda f: f.metadata["load"])
)
# Fields a published row may differ in and still give a row's training seconds per sequence, epoch and
# seed (`studies.machinery.plan.rate_key`).
RATE_NEUTRAL_FIELDS = tuple(f.name for f in _FIELDS if f.metadata.get("rate_neutral"))


def parse_override(text: str) -> tuple[str, Any]:
    """`field=value` as (field, value of the field's type), e.g. "epochs=4", "backbone=tcn",
    "modalities=internal,proprio", "image_size=30,40", "augment_rotation=false". A mistake is a
    one-line `UserError` naming the field and the problem."""
    field, sep, raw = text.partition("=")
    field, raw = field.strip(), raw.strip()
    hints = typing.get_type_hints(Config)
    if not sep or not field:
        raise UserError(f"override {text!r}: expected field=value, e.g. epochs=4")
    if field not in hints:
        raise UserError(f"override {text!r}: Config has no field {field!r}; fields: {', '.join(hints)}")
    try:
        return field, _parse(hints[field], raw)
    except ValueError as e:
        raise UserError(f"override {text!r}: {field} takes {_type_name(hints[field])}: {e}") from None


def format_override(field: str, value: Any) -> str:
    """The `--set` text that `parse_override` reads back as (field, value)."""
    if isinstance(value, tuple):
        return f"{field}={','.join(str(v) for v in value)}"
    return f"{field}={str(value).lower() if isinstance(value, bool) else value}"


def _parse(kind, raw: str) -> Any:
    origin, args = typing.get_origin(kind), typing.get_args(kind)
    if type(None) in args:  # an optional field: "none" unsets it
        return None if raw.lower() == "none" else _parse(next(a for a in args if a is not type(None)), raw)
    if origin is tuple:
        items = [x.strip() for x in raw.split(",") if x.strip()]
        if args[-1] is not Ellipsis and len(items) != len(args):
            raise ValueError(f"{len(items)} values given, {len(args)} expected")
        return tuple(_parse(args[0], x) for x in items)  # Config's tuples hold one type
    if kind is bool:
        if raw.lower() in ("true", "1", "yes"):
            return True
        if raw.lower() in ("false", "0", "no"):
            return False
        raise ValueError(f"{raw!r} is not true or false")
    if kind is int:
        try:
            return int(raw)
        except ValueError:
            raise ValueError(f"{raw!r} is not an integer") from None
    if kind is float:
        try:
            return float(raw)
        except ValueError:
            raise ValueError(f"{raw!r} is not a number") from None
    return raw


def _type_name(kind) -> str:
    return str(kind).replace("typing.", "") if typing.get_args(kind) else kind.__name__
