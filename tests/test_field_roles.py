"""Every `Config` field says what it decides (its metadata's role), and the lists of fields that must
agree (which fields a checkpoint ignores, which a shared load's key holds, which a training rate
ignores) are derived from that metadata."""

import dataclasses
import json

import pytest

from fabricjax import config
from fabricjax.config import Config
from fabricjax.features import extract
from fabricjax.studies.machinery import loading, plan, row_training

# The lists written out by hand, so that a change of a field's metadata that moves one fails here.
RESULT_NEUTRAL = ("input_source",)
SEQUENCE_FIELDS = (
    "preset",
    "seq_len",
    "exclude_fabrics",
    "image_resolution",
    "image_size",
    "flow_sparsify",
    "flow_method",
    "mic_window_s",
    "image_reference",
    "input_source",
)
RATE_NEUTRAL = (
    "preset",
    "n_classes",
    "mic_window_s",
    "input_source",
    "bandwidth_khz",
    "exclude_fabrics",
    "epochs",
    "patience",
    "train_steps",
    "patience_steps",
    "lr_grid",
    "width_grid",
    "learning_rate",
    "width",
    "lr_schedule",
    "warmup_steps",
    "weight_decay",
    "dropout",
    "fusion_norm",
)


@pytest.mark.parametrize("field", dataclasses.fields(Config), ids=lambda f: f.name)
def test_every_config_field_has_a_role(field):
    assert field.metadata.get("role") in config.ROLES, f"Config.{field.name} has no role: {dict(field.metadata)}"
    assert isinstance(field.metadata.get("rate_neutral"), bool), field.name


def test_the_derived_lists_are_the_ones_written_by_hand():
    assert config.RESULT_NEUTRAL_FIELDS == RESULT_NEUTRAL
    assert loading.SEQUENCE_FIELDS == SEQUENCE_FIELDS  # its order builds `loading.sequence_key`
    assert sorted(plan.RATE_NEUTRAL) == sorted(RATE_NEUTRAL)  # a filter: only its members count


def test_every_field_that_decides_the_sequences_is_in_a_loads_key_or_narrowed():
    deciding = {f.name for f in dataclasses.fields(Config) if f.metadata["role"] in (config.SEQUENCES, config.FEATURES)}
    narrowed = {"modalities", "bandwidth_khz"}  # data.narrow gives each row its own
    assert deciding - narrowed <= set(loading.SEQUENCE_FIELDS)
    loads = sorted(f.metadata["load"] for f in dataclasses.fields(Config) if "load" in f.metadata)
    assert loads == list(range(len(loads)))  # one place each in the key


@pytest.mark.parametrize(
    "fields",
    [{}, {"preset": "smoke", "modalities": ("image", "flow"), "width": 32}, {"epochs": 4, "lr_grid": (1e-3, 3e-4)}],
)
def test_rate_keys_are_the_same_strings(fields):
    cfg = Config(**fields).to_json()
    assert plan.rate_key(cfg) == json.dumps({k: v for k, v in sorted(cfg.items()) if k not in RATE_NEUTRAL})


def test_camera_inputs_have_one_spelling():
    assert config.CAMERA_MODALITIES == ("image", "flow")
    assert row_training.ROW_KINDS == ("image", "flow", "other")


@pytest.mark.parametrize(
    "fields",
    [
        {"modalities": ("image", "flow", "internal", "proprio")},
        {"modalities": ("image",), "image_reference": "training_mean", "image_size": (6, 8)},
        {"modalities": ("image", "flow"), "image_resolution": "full", "flow_sparsify": "drop_top"},
        {"modalities": ("internal", "external"), "mic_window_s": 0.05},
    ],
)
def test_features_for_is_feature_for_with_the_configs_fields(fields):
    cfg = Config(**fields)
    rates = {m: 44100 for m in cfg.modalities if m in ("internal", "external")}
    for given, window in ((rates, lambda m: extract.window_of(cfg, rates[m])), (None, lambda m: 2048)):
        got = extract.features_for(cfg, given)
        for m in cfg.modalities:
            f = extract.feature_for(
                m,
                cfg.image_resolution,
                cfg.image_size,
                cfg.flow_sparsify,
                window(m) if m in rates else 2048,
                cfg.image_reference,
                cfg.flow_method,
            )
            assert (got[m].name, got[m].params) == (f.name, f.params)


def test_a_cached_image_feature_keeps_its_name():
    assert extract.feature_named("image_6x8").params == {"size": (6, 8), "interpolation": "area"}
    assert extract.feature_named("image_session_6x8").params["reference"] == "session"


def test_a_choice_outside_its_set_is_refused_in_the_same_words():
    with pytest.raises(ValueError, match=r"^backbone must be one of \('attention', 'tcn'\), got 'lstm'$"):
        Config(backbone="lstm")
    with pytest.raises(ValueError, match=r"^image_resolution must be 'down' or 'full', got 'half'$"):
        Config(image_resolution="half")
