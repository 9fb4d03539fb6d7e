import dataclasses

import pytest

from fabricjax import catalog, config, errors, presets
from fabricjax.store import splits


def test_catalog_complete_and_in_range():
    assert [f.id for f in catalog.FABRICS] == list(range(24))
    for f in catalog.FABRICS:
        for name, n_levels in catalog.PROPERTY_LEVELS.items():
            level = getattr(f, name)
            if f.id == 0:
                assert level is None
            else:
                assert isinstance(level, int) and 0 <= level < n_levels, (f.id, name, level)
        if f.id:
            assert f.weave_period_mm > 0 and f.thickness_mm > 0 and 0 < f.friction < 1.5
    # every level of every property occurs among the training fabrics
    for name, n_levels in catalog.PROPERTY_LEVELS.items():
        seen = {getattr(catalog.fabric(i), name) for i in catalog.TRAINING_FABRICS}
        assert seen == set(range(n_levels)), name
    for fid, word in [(12, "silk"), (21, "silk"), (22, "sweater"), (23, "acrylic"), (4, "synthetic")]:
        assert word in catalog.fabric(fid).name


def test_unknown_fabric():
    with pytest.raises(KeyError, match="unknown fabric id 99"):
        catalog.fabric(99)


def test_paper_preset_matches_protocol():
    p = presets.get("paper").dataset
    trials = p.trials()
    per = lambda fid, day: sum(t.fabric_id == fid and t.day == day for t in trials)  # noqa: E731
    assert per(5, 1) == per(5, 2) == 6 and per(5, 3) == 2 and per(5, 4) == 2
    assert per(22, 1) == 0 and per(22, 3) == 2  # new fabrics are test-only
    assert all(t.condition == "cafe" for t in trials if t.day == 4)
    assert p.image_size == (308, 410)
    assert config.Config.from_preset("paper") == config.Config()  # the paper preset is Config's defaults: N=200
    assert config.Config().seq_len == 200


def test_roles_hold_out_whole_trials():
    metas = [dict(fabric_id=f, day=d, trial=t, condition="lab") for f in (1, 2) for d in (1, 2) for t in range(3)]
    metas += [dict(fabric_id=1, day=3, trial=0, condition="lab"), dict(fabric_id=1, day=4, trial=0, condition="cafe")]
    roles = splits.assign_roles(metas)
    assert roles.count("val") == 4 and roles.count("train") == 8
    assert roles[-2:] == ["test", "cafe"]
    val = [m for m, r in zip(metas, roles) if r == "val"]
    assert all(m["trial"] == 2 for m in val)


def test_config_validation_and_json():
    c = config.Config.from_preset("smoke", modalities=("internal", "proprio"))
    assert config.Config.from_json(c.to_json()) == c
    assert c.seq_len == 20 and c.width == 16 and config.Config.from_preset("default").seq_len == 50
    assert config.Config.from_preset("smoke", seq_len=8, width=4).seq_len == 8  # overrides win over the preset
    # one route from a preset to a config: built directly, a preset's config has its training too
    assert (
        config.Config(preset="default", epochs=3)
        == config.Config.from_preset("default", epochs=3)
        != config.Config(epochs=3)
    )
    with pytest.raises(ValueError, match="modalities"):
        config.Config(modalities=("nose",))
    with pytest.raises(ValueError, match="preset"):
        config.Config(preset="huge")
    with pytest.raises(errors.UserError, match="unknown preset 'huge'; choose one of"):
        config.Config.from_preset("huge")
    with pytest.raises(errors.UserError, match="chosen by name"):
        config.Config.from_preset("smoke", preset="paper")


def test_config_from_json_before_seq_len_was_explicit():
    """Checkpoints and results stored `seq_len: null` for the preset's N: they read back as that N."""
    stored = {**config.Config.from_preset("smoke").to_json(), "seq_len": None}
    assert config.Config.from_json(stored).seq_len == 20


def test_every_config_field_round_trips_through_an_override():
    c = config.Config.from_preset(
        "default", modalities=("internal", "proprio"), exclude_fabrics=(1, 10), augment_rotation=False
    )
    for field, value in c.to_json().items():
        value = tuple(value) if isinstance(value, list) else value
        assert config.parse_override(config.format_override(field, value)) == (field, value)
    assert config.parse_override("learning_rate=2e-3") == ("learning_rate", 0.002)
    assert config.parse_override(" epochs = 4 ") == ("epochs", 4)


@pytest.mark.parametrize(
    "text, message",
    [
        ("epochs=two", "override 'epochs=two': epochs takes int: 'two' is not an integer"),
        ("colour=red", "Config has no field 'colour'"),
        ("epochs", "expected field=value"),
        ("image_size=30", r"image_size takes tuple\[int, int\]: 1 values given, 2 expected"),
        ("augment_rotation=maybe", "'maybe' is not true or false"),
    ],
)
def test_bad_overrides_are_one_line_errors(text, message):
    with pytest.raises(errors.UserError, match=message) as e:
        config.parse_override(text)
    assert "\n" not in str(e.value)


def test_presets_are_named_keyword_built_and_build_configs():
    for name, p in presets.PRESETS.items():
        assert p.name == name and p.dataset.trials()
        assert config.Config.from_preset(name).preset == name
        unknown = set(p.training) - {f.name for f in dataclasses.fields(config.Config)}
        assert not unknown, f"preset {name} sets unknown Config fields {unknown}"
    with pytest.raises(TypeError):
        splits.DatasetSpec((0,), 1, 1, 1, 1, (8, 8))  # keyword-only: no positional fields to mix up
