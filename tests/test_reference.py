"""Minsight read as its own software reads it: each session's no-contact reference travels in the
trial archive (format 3), from the simulator and the recorder, and frames can be read against it."""

import json

import numpy as np
import pytest

from fabricjax import sim
from fabricjax.config import Config
from fabricjax.features import extract, images
from fabricjax.store import archive
from tests.helpers import CountingCamera, npz_fields, tiny_archive


def test_the_reference_survives_a_round_trip(tmp_path):
    a = tiny_archive()
    assert a.reference.shape == (1, 12, 16, 3) and a.meta["format_version"] == archive.FORMAT_VERSION == 3
    b = archive.read_archive(archive.write_archive(tmp_path / "t.npz", a))
    np.testing.assert_array_equal(b.reference, a.reference)
    assert b.meta["reference"] == a.meta["reference"] and archive.reference_note(b.meta) is None
    assert (
        archive.read_archive(tmp_path / "t.npz", images=False).reference is not None
    )  # small: read without the frames too


def _meta(**changes):
    m = tiny_archive().meta
    m.update(changes)
    return np.array(json.dumps(m))


@pytest.mark.parametrize(
    "changes, field, words",
    [
        ({"reference": None}, "reference", "missing: meta.reference describes"),
        (
            {"meta": np.array(json.dumps({k: v for k, v in tiny_archive().meta.items() if k != "reference"}))},
            "meta.reference",
            "say how and when",
        ),
        ({"reference": np.zeros((1, 5, 5, 3), np.uint8)}, "reference", "image_size"),
        ({"reference": np.zeros((0, 12, 16, 3), np.uint8)}, "reference", "0 frames"),
        ({"reference": np.zeros((1, 12, 16, 3), np.float32)}, "reference", "dtype"),
        (
            {"meta": _meta(reference={"how": "x", "session": "s", "times_s": [1.0, 2.0]})},
            "meta.reference.times_s",
            "1 finite times",
        ),
        ({"meta": _meta(reference={"how": "", "session": "s", "times_s": None})}, "meta.reference.how", "non-empty"),
        ({"meta": _meta(format_version=2)}, "reference", "format 2 has no session reference"),
    ],
)
def test_a_bad_reference_is_one_line_naming_the_field(tmp_path, changes, field, words):
    p = tmp_path / "bad.npz"
    np.savez(p, **npz_fields(tiny_archive(), **changes))
    with pytest.raises(archive.ArchiveError) as e:
        archive.read_archive(p)
    assert (e.value.field, "\n" in str(e.value)) == (field, False) and words in e.value.problem, str(e.value)


def test_a_camera_free_archive_needs_no_reference_and_may_hold_none(tmp_path):
    a = tiny_archive(images=None)
    assert a.reference is None and archive.reference_note(a.meta) is None
    p = tmp_path / "bad.npz"
    np.savez(
        p,
        **npz_fields(
            a,
            reference=np.zeros((1, 12, 16, 3), np.uint8),
            meta=np.array(json.dumps({**a.meta, "reference": {"how": "x", "session": "s", "times_s": None}})),
        ),
    )
    with pytest.raises(archive.ArchiveError, match="declares no camera|declared image_size None"):
        archive.read_archive(p)


def test_archives_of_the_previous_format_still_load_and_say_they_have_no_reference(tmp_path):
    a = tiny_archive(reference=False)
    old = {**a.meta, "format_version": 2}
    p = tmp_path / "old.npz"
    np.savez(p, **npz_fields(a, meta=np.array(json.dumps(old))))
    b = archive.read_archive(p)
    assert b.reference is None and "format-2 archive" in archive.reference_note(b.meta)
    feature = extract.feature_for("image", image_size=(6, 8), image_reference="session")
    assert feature.needs_reference and feature.name == "image_session_6x8"


def test_subtracting_the_reference_is_exact_without_wrap_around():
    frames = np.zeros((3, 4, 6, 3), np.uint8)
    frames[1], frames[2] = 255, 7
    reference = np.full((1, 4, 6, 3), 255, np.uint8)
    reference[0, :, :, 1] = 0
    d = images.session_difference(frames, reference, (2, 3))
    step = images.DIFFERENCE_SCALE  # the difference's units per grey level
    assert d.dtype == np.int16 and d.shape == (3, 2, 3, 3)
    np.testing.assert_array_equal(d[0, ..., 0], -255 * step)
    np.testing.assert_array_equal(d[1, ..., 1], 255 * step)
    np.testing.assert_array_equal(d[2], step * (7 - images.downsample(reference, (2, 3))[0].astype(np.int16)))
    two = np.concatenate([reference, np.zeros_like(reference)])  # several frames: their mean, not rounded
    np.testing.assert_array_equal(images.session_difference(frames[:1], two, (2, 3))[0, ..., 0], -127.5 * step)


def test_a_difference_below_one_grey_level_survives_the_downsampling():
    """Area-downsampling averages many camera pixels: a contact that brightens one pixel in four by
    one grey level is a quarter of a grey level in the downsampled frame, which whole grey levels
    would round to nothing."""
    reference = np.full((1, 4, 4, 3), 100, np.uint8)
    frames = reference.copy()
    frames[0, 0, 0] = 101
    d = images.session_difference(frames, reference, (2, 2))
    assert d[0, 0, 0, 0] == images.DIFFERENCE_SCALE // 4 and (d[0, 1:] == 0).all()


def test_the_simulator_writes_each_session_s_reference():
    def trial(day, trial_index):
        scene = sim.Scene(
            fabric_id=4,
            day=day,
            trial=trial_index,
            condition="lab",
            streams=sim.STREAMS,
            image_size=(30, 40),
            cycles=1,
            seed=0,
        )
        return sim.simulate(scene)

    a, b, c = trial(1, 0), trial(1, 1), trial(2, 0)
    assert a.reference.shape == (archive.REFERENCE_FRAMES, 30, 40, 3) and a.meta["reference"]["session"] == "day1_lab"
    np.testing.assert_array_equal(a.reference, b.reference)  # one session, one reference
    assert not np.array_equal(a.reference, c.reference) and c.meta["reference"]["session"] == "day2_lab"
    # the difference reads the contact: no-contact steps (the grasp's start) are near the reference, rubbing moves it
    d = images.session_difference(a.images, a.reference, (30, 40)).astype(np.float32)
    assert np.abs(d[0]).mean() < np.abs(d).mean(axis=(1, 2, 3)).max()


def test_session_is_a_reading_of_the_config():
    assert Config(image_reference="session").image_reference == "session"
    with pytest.raises(ValueError, match="image_reference must be one of"):
        Config(image_reference="yesterday")


def test_the_recorder_takes_the_reference_as_minsight_s_node_does():
    from acquisition import camera

    cam = CountingCamera(dropped=5)
    ref = camera.take_reference(cam, "day3_lab", n_frames=2)
    # the warm-up frames are discarded, the next frames kept; repeats during the warm-up are not the trial's drops
    assert [int(f[0, 0, 0]) for f in ref.frames] == [
        camera.WARMUP_FRAMES,
        camera.WARMUP_FRAMES + 1,
    ] and cam.dropped == 0
    meta = ref.meta(t0=ref.taken_at[1] + 2.0)
    assert (
        meta["session"] == "day3_lab"
        and np.allclose(meta["times_s"][1], -2.0)
        and meta["times_s"][0] < meta["times_s"][1]
    )
    assert "after 20 warm-up frames" in meta["how"]
