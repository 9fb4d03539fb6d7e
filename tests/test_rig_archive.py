"""Archives of rigs unlike the paper's hand: the meta declares the streams (issue 26), and
archives written before (format version 1) read unchanged."""

import json

import numpy as np
import pytest

from fabricjax import catalog
from fabricjax.store import archive
from tests.helpers import tiny_archive

ARM = [f"arm_{k}" for k in range(7)]


def v1_meta(fabric_id=4, image_size=(12, 16)):
    """The meta exactly as the format-1 writer made it (archive.make_meta before layouts)."""
    return {
        "format_version": 1,
        "fabric_id": fabric_id,
        "label": fabric_id,
        "properties": dict(catalog.fabric(fabric_id).properties),
        "day": 1,
        "trial": 0,
        "condition": "lab",
        "source": {"kind": "test"},
        "sample_rates": {"audio": 48000, "steps": 50},
        "image_size": list(image_size),
        "joint_names": list(archive.JOINT_NAMES),
        "joint_fields": ["angle", "velocity", "current"],
        "mic_names": ["internal", "external"],
        "units": {
            "timestamps": "s",
            "joints": ["rad", "rad/s", "A"],
            "force": "N",
            "audio": "SPH0645 I2S word (int32; 18 valid bits in bits 31..14)",
        },
        "complete": True,
    }


def rig_streams(mics=(("vibration", 2200, "internal"),), joints=ARM, camera=None):
    return {
        "mics": [{"name": n, "rate": r, "role": role} for n, r, role in mics],
        "joints": None
        if joints is None
        else {"names": list(joints), "fields": ["angle", "velocity", "torque"], "units": ["rad", "rad/s", "N m"]},
        "camera": camera,
        "force": None,
        "steps": {"clock": "rate", "rate": 50},
    }


def rig_archive(n_steps=40, streams=None, **meta):
    streams = streams or rig_streams()
    lay_mics = len(streams["mics"])
    rng = np.random.default_rng(0)
    n_samples = archive.WINDOW + 44 * n_steps  # 2200 Hz / 50 Hz = 44 samples per step
    m = archive.make_meta(
        label=2,
        properties={},
        day=None,
        trial=3,
        condition=None,
        source={"kind": "test"},
        image_size=None,
        streams=streams,
        label_map={"oak": 0, "pine": 1, "felt": 2},
        label_name="felt",
        **meta,
    )
    joints = streams["joints"]
    return archive.TrialArchive(
        meta=m,
        timestamps=np.arange(n_steps) / 50.0,
        window_end=np.stack([archive.WINDOW + 44 * np.arange(n_steps)] * lay_mics, axis=1).astype(np.int64),
        joints=None if joints is None else rng.normal(size=(n_steps, len(joints["names"]), 3)).astype(np.float32),
        force=None,
        audio=(rng.integers(-(2**17), 2**17, size=(lay_mics, n_samples)) << 14).astype(np.int32),
    )


def test_format_1_archive_reads_unchanged_as_the_hand(tmp_path):
    a = tiny_archive(reference=False)  # format 1 has no session reference
    p = tmp_path / "old.npz"
    np.savez(p, meta=np.array(json.dumps(v1_meta())), **a.arrays())
    b = archive.read_archive(p)
    assert b.meta == v1_meta()  # nothing rewritten
    lay = archive.layout(b.meta)
    assert [(m.name, m.rate, m.role) for m in lay.mics] == [
        ("internal", 48000, "internal"),
        ("external", 48000, "external"),
    ]
    assert lay.joint_names == archive.JOINT_NAMES and lay.joint_units == ("rad", "rad/s", "A")
    assert lay.image_size == (12, 16) and lay.force and lay.step_rate == 50
    np.testing.assert_array_equal(b.audio, a.audio)
    assert archive.n_classes(b.meta) is None  # the catalog's classes


def test_format_1_archive_of_a_30_fps_position_only_import_reads_unchanged(tmp_path):
    """Format-1 archives that issue 27's importer wrote: the camera's own step rate in
    sample_rates.steps and the fields a JointState lacked in joint_fields_absent (NaN)."""
    a = tiny_archive(reference=False)  # format 1 has no session reference
    joints = a.joints.copy()
    joints[..., 1:] = np.nan
    meta = {**v1_meta(), "sample_rates": {"audio": 48000, "steps": 30}, "joint_fields_absent": ["velocity", "current"]}
    p = tmp_path / "old.npz"
    np.savez(p, meta=np.array(json.dumps(meta)), **{**a.arrays(), "joints": joints})
    b = archive.read_archive(p)
    assert b.meta == meta
    lay = archive.layout(b.meta)
    assert lay.step_rate == 30 and lay.step_clock == "camera" and lay.joint_fields_absent == ("velocity", "current")
    assert "proprio" not in lay.modalities() and "velocity [rad/s] (not recorded)" in lay.describe()
    np.savez(p, meta=np.array(json.dumps(meta)), **{**a.arrays(), "joints": np.nan_to_num(joints)})
    with pytest.raises(
        archive.ArchiveError, match=r"'joints': fields \['velocity', 'current'\] are recorded as absent but hold values"
    ):
        archive.read_archive(p)
    for bad, field in [
        ({"joint_fields_absent": ["torque"]}, "meta.joint_fields_absent"),
        ({"sample_rates": {"audio": 48000, "steps": 0}}, "meta.sample_rates.steps"),
    ]:
        np.savez(p, meta=np.array(json.dumps({**meta, **bad})), **{**a.arrays(), "joints": joints})
        with pytest.raises(archive.ArchiveError) as e:
            archive.read_archive(p)
        assert e.value.field == field


def test_absent_joint_fields_in_format_2(tmp_path):
    """Format 2 says which joint fields were not recorded in streams.joints.absent (one
    representation: format 1's top-level joint_fields_absent is refused there)."""
    streams = rig_streams()
    streams["joints"]["absent"] = ["torque"]
    a = rig_archive(streams=streams)
    a.joints[..., 2] = np.nan
    b = archive.read_archive(archive.write_archive(tmp_path / "a.npz", a))
    assert archive.layout(b.meta).joint_fields_absent == ("torque",) and np.isnan(b.joints[..., 2]).all()
    assert archive.layout(b.meta).modalities() == ("internal",)
    a.joints[..., 1] = np.nan  # NaN in a recorded field is still refused
    with pytest.raises(archive.ArchiveError, match="'joints': 280 non-finite values"):
        archive.write_archive(tmp_path / "b.npz", a)
    streams["joints"]["absent"] = ["current"]
    with pytest.raises(archive.ArchiveError) as e:
        archive.write_archive(tmp_path / "c.npz", rig_archive(streams=streams))
    assert e.value.field == "meta.streams.joints.absent"
    with pytest.raises(archive.ArchiveError) as e:
        archive.write_archive(tmp_path / "d.npz", rig_archive(joint_fields_absent=["torque"]))
    assert (
        e.value.field == "meta.joint_fields_absent"
        and "format 2 lists absent joint fields in meta.streams.joints.absent" in e.value.problem
    )
    assert not (tmp_path / "c.npz").exists() and not (tmp_path / "d.npz").exists()


def test_rig_without_camera_force_or_palm_mic_round_trips(tmp_path):
    a = rig_archive()
    p = archive.write_archive(tmp_path / archive.trial_filename(a.meta), a)
    assert p.name == "felt_trial003.npz"
    b = archive.read_archive(p)
    assert b.images is None and b.force is None and b.joints.shape == (40, 7, 3)
    lay = archive.layout(b.meta)
    assert lay.modalities() == ("internal", "proprio")
    assert lay.mics[0].nyquist_khz == 1.1
    assert "vibration (2200 Hz, feeds internal)" in lay.describe() and "no camera" in lay.describe()
    assert "torque [N m]" in lay.describe()
    assert archive.n_classes(b.meta) == 3
    assert b.meta["properties"] == {}  # nothing stamped from the catalog


@pytest.mark.parametrize(
    "change, field, words",
    [
        (dict(joints=None), "joints", "missing"),
        (dict(joints=np.zeros((40, 6, 3), np.float32)), "joints", "shape"),
        (dict(force=np.zeros(40, np.float32)), "force", "declares no force"),
        (dict(window_end=np.zeros((40, 2), np.int64)), "window_end", "shape"),
    ],
)
def test_arrays_must_match_the_declared_streams(tmp_path, change, field, words):
    import dataclasses

    bad = dataclasses.replace(rig_archive(), **change)
    with pytest.raises(archive.ArchiveError) as e:
        archive.write_archive(tmp_path / "x.npz", bad)
    assert e.value.field == field and words in e.value.problem
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    "streams, meta, field",
    [
        (rig_streams(mics=(("a", 2200, "internal"), ("b", 2200, "internal"))), {}, "meta.streams.mics"),
        (rig_streams(mics=(("a", 0, "internal"),)), {}, "meta.streams.mics[0].rate"),
        (rig_streams(mics=(("a", 2200, "palm"),)), {}, "meta.streams.mics[0].role"),
        ({**rig_streams(), "steps": {"clock": "sundial", "rate": 50}}, {}, "meta.streams.steps.clock"),
        (rig_streams(), {"split": "later"}, "meta.split"),
    ],
)
def test_bad_stream_declarations_are_named(tmp_path, streams, meta, field):
    with pytest.raises(archive.ArchiveError) as e:
        archive.write_archive(tmp_path / "x.npz", rig_archive(streams=streams, **meta))
    assert e.value.field == field


def test_label_map_must_name_every_class(tmp_path):
    a = rig_archive()
    a.meta["label_map"] = {"oak": 0, "felt": 2}
    with pytest.raises(archive.ArchiveError, match="label_map"):
        archive.write_archive(tmp_path / "x.npz", a)
