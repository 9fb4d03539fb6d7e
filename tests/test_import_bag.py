"""ROS 2 bags written with rosbags' own writer become archives aligned as the recorder aligns."""

import re
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from fabricjax.importers.streams import RecordingImportError
from fabricjax.store import archive

pytest.importorskip("rosbags")

from rosbags.rosbag2 import StoragePlugin, Writer  # noqa: E402

from fabricjax.importers import ros_bag, ros_messages  # noqa: E402

TS = ros_messages.typestore_for([])  # ROS 2 Humble's types and audio_common's
T0 = 100.0  # s, the first frame's stamp
N_FRAMES, CHUNK, H, W = 20, 960, 8, 10
NAMES = list(archive.JOINT_NAMES)
REFERENCE = "/minsight/reference"
REFERENCE_T = (T0 - 0.5, T0 - 0.3, T0 + 0.1)  # s: two no-contact frames before the trial, one republished during it
MAPPING = {
    "camera": {"topic": "/minsight/image", "reference_topic": REFERENCE},
    "mics": {
        "internal": {"topic": "/minsound/audio", "rate": 48000},
        "external": {"topic": "/palm/audio", "rate": 48000},
    },
    "joints": {"topic": "/joint_states"},
    "trial": {"fabric_id": 4, "day": 2, "trial": 3, "condition": "lab"},
}
MAPPING_TOML = """\
[camera]
topic = "/minsight/image"
reference_topic = "/minsight/reference"

[mics.internal]
topic = "/minsound/audio"
rate = 48000

[mics.external]
topic = "/palm/audio"
rate = 48000

[joints]
topic = "/joint_states"

[trial]
fabric_id = 4
day = 2
trial = 3
condition = "lab"
"""


def _header(t):
    sec = int(t)
    return TS.types["std_msgs/msg/Header"](
        stamp=TS.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((t - sec) * 1e9))), frame_id=""
    )


def _layout():
    return TS.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)


def recording(seed=0, n_frames=N_FRAMES):
    """Frames at 50 Hz from T0; 960-sample chunks whose ends fall 5 ms after each frame slot, from
    0.1 s before T0 (5 chunks = a full window at the first frame); joints at 100 Hz; reference
    frames at REFERENCE_T."""
    rng = np.random.default_rng(seed)
    frames = rng.integers(0, 255, size=(n_frames, H, W, 3), dtype=np.uint8)
    n_chunks = n_frames + 5
    internal = rng.integers(-(2**15), 2**15, size=(n_chunks, CHUNK), dtype=np.int16)
    external = (rng.integers(-(2**17), 2**17, size=(n_chunks, CHUNK)) << 14).astype(np.int32)
    chunk_end = T0 - 0.1 + 0.005 + 0.02 * np.arange(n_chunks)
    joint_t = T0 - 0.05 + 0.01 * np.arange(2 * n_frames + 5)
    joints = rng.normal(size=(len(joint_t), 6, 3))
    reference = rng.integers(0, 255, size=(len(REFERENCE_T), H, W, 3), dtype=np.uint8)
    return dict(
        frames=frames,
        internal=internal,
        external=external,
        chunk_end=chunk_end,
        joint_t=joint_t,
        joints=joints,
        reference=reference,
    )


def write_bag(path, rec, *, storage="sqlite3", qos=None, **options):
    """Write `rec` (`bag_messages` with `options`) as a ROS 2 bag."""
    return write_messages(path, bag_messages(rec, **options), storage=storage, qos=qos)


def write_messages(path, msgs, *, storage="sqlite3", qos=None):
    """(receive time s, topic, type, message) as a rosbag2 folder, as rosbag2 records: one
    connection per topic, messages in the order given; `qos`: {topic: offered QoS profiles}."""
    plugin = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage]
    with Writer(path, version=8, storage_plugin=plugin) as writer:
        conns = {}
        for t, topic, typ, msg in msgs:
            if topic not in conns:
                conns[topic] = writer.add_connection(
                    topic, typ, typestore=TS, offered_qos_profiles=(qos or {}).get(topic, ())
                )
            writer.write(conns[topic], int(round(t * 1e9)), TS.serialize_cdr(msg, typ))
    return Path(path)


def bag_messages(rec, *, compressed=False, shuffle=False, drop_frame=None, drop_chunk=None):
    """`rec`'s messages (receive time, topic, type, message); `shuffle` puts them out of time order
    (receive time of frames and joints then disagrees with their header stamps, which place them)."""
    msgs = []  # (receive time, topic, type, message)
    for i, img in enumerate(rec["frames"]):
        if i == drop_frame:
            continue
        t = T0 + 0.02 * i
        if compressed:
            ok, png = cv2.imencode(".png", cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
            msg = TS.types["sensor_msgs/msg/CompressedImage"](header=_header(t), format="png", data=png.ravel())
            msgs.append((t + 0.001, "/minsight/image", "sensor_msgs/msg/CompressedImage", msg))
        else:
            msg = TS.types["sensor_msgs/msg/Image"](
                header=_header(t), height=H, width=W, encoding="rgb8", is_bigendian=0, step=W * 3, data=img.ravel()
            )
            msgs.append((t + 0.001, "/minsight/image", "sensor_msgs/msg/Image", msg))
    msgs += [reference_message(t, img) for t, img in zip(REFERENCE_T, rec["reference"])]
    for k, t in enumerate(rec["chunk_end"]):
        if k == drop_chunk:
            continue
        msgs.append(
            (
                t,
                "/minsound/audio",
                "std_msgs/msg/Int16MultiArray",
                TS.types["std_msgs/msg/Int16MultiArray"](layout=_layout(), data=rec["internal"][k]),
            )
        )
        msgs.append(
            (
                t,
                "/palm/audio",
                "std_msgs/msg/Int32MultiArray",
                TS.types["std_msgs/msg/Int32MultiArray"](layout=_layout(), data=rec["external"][k]),
            )
        )
    for t, q in zip(rec["joint_t"], rec["joints"]):
        msg = TS.types["sensor_msgs/msg/JointState"](
            header=_header(t), name=NAMES, position=q[:, 0].copy(), velocity=q[:, 1].copy(), effort=q[:, 2].copy()
        )
        msgs.append((t + 0.002, "/joint_states", "sensor_msgs/msg/JointState", msg))
    if shuffle:
        order = np.random.default_rng(1).permutation(len(msgs))
        msgs = [msgs[i] for i in order]
        # frames and joints arrive late and in bursts: receive times no longer follow the stamps
        msgs = [
            (t + (0.05 if topic in ("/minsight/image", "/joint_states") and i % 3 == 0 else 0.0), topic, typ, m)
            for i, (t, topic, typ, m) in enumerate(msgs)
        ]
    return msgs


def reference_message(t, img):
    """A no-contact frame taken at `t`, received 1 ms later."""
    msg = TS.types["sensor_msgs/msg/Image"](
        header=_header(t), height=H, width=W, encoding="rgb8", is_bigendian=0, step=W * 3, data=img.ravel()
    )
    return (t + 0.001, REFERENCE, "sensor_msgs/msg/Image", msg)


def expected_window_end(n=N_FRAMES):
    # chunk k ends at T0 - 0.095 + 0.02 k: frame i (at T0 + 0.02 i) follows chunks 0..4+i
    return CHUNK * (5 + np.arange(n))


def check_fields(a, rec):
    assert a.n_steps == N_FRAMES
    np.testing.assert_allclose(a.timestamps, 0.02 * np.arange(N_FRAMES), atol=1e-6)
    np.testing.assert_array_equal(a.window_end, np.stack([expected_window_end()] * 2, axis=1))
    np.testing.assert_array_equal(a.audio[0], rec["internal"].ravel().astype(np.int32) << 16)
    np.testing.assert_array_equal(a.audio[1], rec["external"].ravel())
    np.testing.assert_array_equal(a.images, rec["frames"])
    # latest joint reading at or before frame i (T0 + 0.02 i) is joint sample 5 + 2 i
    np.testing.assert_allclose(a.joints, rec["joints"][5 + 2 * np.arange(N_FRAMES)].astype(np.float32), rtol=1e-6)
    assert a.meta["fabric_id"] == 4 and a.meta["day"] == 2 and a.meta["trial"] == 3
    assert archive.layout(a.meta).image_size == (H, W)
    assert a.meta["import"]["frame_gaps"] == []
    assert archive.layout(a.meta).step_rate == 50 and "absent" not in a.meta["streams"]["joints"]
    np.testing.assert_array_equal(
        a.reference, rec["reference"][:2]
    )  # the frames before the trial's first, not the one during it
    assert a.meta["reference"]["how"] == f"imported: 2 frames of {REFERENCE}, up to the trial's first camera frame"
    assert a.meta["reference"]["session"] == "day2_lab" and a.meta["source"]["reference"] == REFERENCE


@pytest.mark.parametrize("compressed,storage", [(False, "sqlite3"), (True, "mcap")])
def test_bag_becomes_aligned_archive(tmp_path, compressed, storage):
    rec = recording()
    bag = write_bag(tmp_path / "bag", rec, compressed=compressed, shuffle=True, storage=storage)
    a = ros_bag.import_bag(bag, MAPPING, MAPPING["trial"])
    path = archive.write_archive(tmp_path / "out" / archive.trial_filename(a.meta), a)
    back = archive.read_archive(path)
    check_fields(back, rec)
    assert back.meta["reference"]["times_s"] == pytest.approx([-0.5, -0.3])  # header stamps, on the trial's step clock


def test_a_camera_without_a_reference_is_a_one_line_error_and_pre_contact_is_only_taken_when_asked(tmp_path):
    rec = recording()
    bag = write_bag(tmp_path / "bag", rec)
    camera = {"topic": "/minsight/image"}
    with pytest.raises(ros_bag.BagError) as e:
        ros_bag.import_bag(bag, {**MAPPING, "camera": camera}, MAPPING["trial"])
    assert str(e.value) == (
        "mapping: camera.reference_topic: missing: a camera needs its session's no-contact reference: name the topic "
        'that carries it (set reference_topic = "/minsight/reference"), or set reference = "pre_contact" to '
        "use the trial's first frames"
    )
    a = ros_bag.import_bag(
        bag, {**MAPPING, "camera": {**camera, "reference": "pre_contact", "reference_frames": 3}}, MAPPING["trial"]
    )
    a = archive.read_archive(archive.write_archive(tmp_path / archive.trial_filename(a.meta), a))
    np.testing.assert_array_equal(a.reference, rec["frames"][:3])
    assert a.meta["reference"] == {
        "how": "imported: the trial's first 3 frames (pre-contact, as the mapping asks)",
        "session": "day2_lab",
        "times_s": pytest.approx([0.0, 0.02, 0.04]),
    }
    for table, words in [
        ({**MAPPING["camera"], "reference": "pre_contact"}, "camera.reference_topic: given with camera.reference"),
        ({**MAPPING["camera"], "reference_frames": 2}, "camera.reference_frames: given with a named source"),
        (
            {**camera, "reference": "pre_contact", "reference_frames": 0},
            "camera.reference_frames: must be an integer in [1, 256]",
        ),
        ({**camera, "reference_topic": "/minsight/image"}, "camera.reference_topic: is camera.topic"),
    ]:
        with pytest.raises(ros_bag.BagError, match=re.escape(words)):
            ros_bag.import_bag(bag, {**MAPPING, "camera": table}, MAPPING["trial"])
    no_reference = write_messages(tmp_path / "bag2", [m for m in bag_messages(rec) if m[1] != REFERENCE])
    with pytest.raises(ros_bag.BagError, match=r"topics \['/minsight/reference'\] not in the bag"):
        ros_bag.import_bag(no_reference, MAPPING, MAPPING["trial"])
    others = [m for m in bag_messages(rec) if m[1] != REFERENCE]
    once = ros_bag.import_bag(
        write_messages(tmp_path / "bag3", [*others, reference_message(T0 + 0.1, rec["reference"][2])]),
        MAPPING,
        MAPPING["trial"],
    )
    np.testing.assert_array_equal(
        once.reference, rec["reference"][2:]
    )  # published once (latched): taken whenever it came
    assert once.meta["reference"]["how"] == f"imported: the one frame of {REFERENCE} (published once)"
    assert once.meta["reference"]["times_s"] == pytest.approx([0.1])
    late = [*others, *(reference_message(T0 + dt, img) for dt, img in zip((0.1, 0.2), rec["reference"]))]
    with pytest.raises(
        ros_bag.BagError, match=r"/minsight/reference: none of its 2 frames comes before the trial's first camera frame"
    ):
        ros_bag.import_bag(write_messages(tmp_path / "bag4", late), MAPPING, MAPPING["trial"])


def test_missing_frame_is_a_reported_gap(tmp_path):
    rec = recording()
    a = ros_bag.import_bag(write_bag(tmp_path / "bag", rec, drop_frame=7), MAPPING, MAPPING["trial"])
    assert a.n_steps == N_FRAMES - 1
    assert a.meta["import"]["frame_gaps"] == [{"step": 7, "seconds": pytest.approx(0.04, abs=1e-6)}]
    archive.validate(a)


def test_missing_audio_message_is_an_error(tmp_path):
    bag = write_bag(tmp_path / "bag", recording(), drop_chunk=10)
    with pytest.raises(RecordingImportError, match=r"/minsound/audio: audio: about 0\.02\d* s of samples missing"):
        ros_bag.import_bag(bag, MAPPING, MAPPING["trial"])


def test_wrong_rate_is_an_error_unless_resampled(tmp_path):
    bag = write_bag(tmp_path / "bag", recording())
    mapping = {**MAPPING, "mics": {**MAPPING["mics"], "external": {"topic": "/palm/audio", "rate": 44100}}}
    with pytest.raises(RecordingImportError, match=r"^/palm/audio: rate: sample rate 44100 Hz"):
        ros_bag.import_bag(bag, mapping, MAPPING["trial"])
    a = ros_bag.import_bag(bag, mapping, MAPPING["trial"], resample=True)
    assert a.meta["import"]["resampled"]["/palm/audio"]["from_hz"] == 44100
    archive.validate(a)


def test_missing_topic_is_named(tmp_path):
    bag = write_bag(tmp_path / "bag", recording())
    mapping = {**MAPPING, "joints": {"topic": "/hand/joints"}}
    with pytest.raises(
        ros_bag.BagError, match=r"bag: topics \['/hand/joints'\] not in the bag \(it has \['/joint_states', "
    ):
        ros_bag.import_bag(bag, mapping, MAPPING["trial"])


def test_command_writes_archive_and_reports_errors_in_one_line(tmp_path):
    rec = recording()
    bag = write_bag(tmp_path / "bag", rec)
    (tmp_path / "map.toml").write_text(MAPPING_TOML)
    cmd = [
        sys.executable,
        "-m",
        "experiments.import_bag",
        str(bag),
        f"--map={tmp_path / 'map.toml'}",
        f"--out={tmp_path / 'out'}",
    ]
    done = subprocess.run(cmd + ["--trial=5"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert archive.read_archive(tmp_path / "out" / "fabric04_day2_trial05_lab.npz").meta["trial"] == 5
    (tmp_path / "bad.toml").write_text(MAPPING_TOML.replace('[joints]\ntopic = "/joint_states"\n', ""))
    done = subprocess.run(
        cmd[:4] + [f"--map={tmp_path / 'bad.toml'}", cmd[5]], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [f"error: {tmp_path / 'bad.toml'}: joints.topic: missing"]
    (tmp_path / "bad.toml").write_text(MAPPING_TOML.replace('reference_topic = "/minsight/reference"\n', ""))
    done = subprocess.run(
        cmd[:4] + [f"--map={tmp_path / 'bad.toml'}", f"--out={tmp_path / 'out2'}"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2 and not (tmp_path / "out2").exists()
    assert done.stderr.strip().splitlines() == [
        f"error: {tmp_path / 'bad.toml'}: camera.reference_topic: missing: a camera needs its session's "
        'no-contact reference: name the topic that carries it (set reference_topic = "/minsight/reference"), '
        'or set reference = "pre_contact" to use the trial\'s first frames'
    ]
