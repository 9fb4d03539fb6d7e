import pytest

from fabricjax import catalog, config, splits


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
    p = splits.preset("paper")
    trials = p.trials()
    per = lambda fid, day: sum(t.fabric_id == fid and t.day == day for t in trials)  # noqa: E731
    assert per(5, 1) == per(5, 2) == 6 and per(5, 3) == 2 and per(5, 4) == 2
    assert per(22, 1) == 0 and per(22, 3) == 2  # new fabrics are test-only
    assert all(t.condition == "cafe" for t in trials if t.day == 4)
    assert p.seq_len == 200 and p.image_size == (308, 410)


def test_roles_hold_out_whole_trials():
    metas = [dict(fabric_id=f, day=d, trial=t, condition="lab") for f in (1, 2) for d in (1, 2) for t in range(3)]
    metas += [dict(fabric_id=1, day=3, trial=0, condition="lab"), dict(fabric_id=1, day=4, trial=0, condition="cafe")]
    roles = splits.assign_roles(metas)
    assert roles.count("val") == 4 and roles.count("train") == 8
    assert roles[-2:] == ["test", "cafe"]
    val = [m for m, r in zip(metas, roles) if r == "val"]
    assert all(m["trial"] == 2 for m in val)


def test_config_validation_and_json():
    c = config.Config(modalities=("internal", "proprio"), preset="smoke")
    assert config.Config.from_json(c.to_json()) == c
    assert c.sequence_length == 20
    with pytest.raises(ValueError, match="modalities"):
        config.Config(modalities=("nose",))
    with pytest.raises(ValueError, match="preset"):
        config.Config(preset="huge")
