"""ROS 2 bags as labs record them (issue 27): audio_common audio, clocks that disagree, a 30 fps
camera, position-only joint states, and every problem of a bag named in one line. Each case is
built with rosbags' writer as rosbag2 records (tests.test_import_bag's helpers)."""

import sqlite3
import subprocess
import sys

import numpy as np
import pytest

from fabricjax.importers import mapping_file
from fabricjax.importers.streams import RecordingImportError
from fabricjax.store import archive, integrity

pytest.importorskip("rosbags")

from fabricjax.importers import ros_bag  # noqa: E402
from tests.test_import_bag import (  # noqa: E402
    MAPPING,
    MAPPING_TOML,
    N_FRAMES,
    NAMES,
    REFERENCE,
    T0,
    TS,
    _header,
    bag_messages,
    check_fields,
    recording,
    write_bag,
    write_messages,
)

TRIAL = MAPPING["trial"]
CAMERA, JOINTS, INTERNAL, EXTERNAL = "/minsight/image", "/joint_states", "/minsound/audio", "/palm/audio"


def _mapping(**tables):
    """MAPPING with some tables replaced or extended (`camera={"clock": "device"}` adds a key)."""
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in MAPPING.items()}
    out["mics"] = {m: dict(t) for m, t in MAPPING["mics"].items()}
    for name, table in tables.items():
        if name in archive.MIC_NAMES:
            out["mics"][name].update(table)
        else:
            out.setdefault(name, {}).update(table)
    return out


def _restamp(msgs, topic, stamp):
    """The messages with `topic`'s header stamps replaced by stamp(old stamp in s)."""
    out = []
    for t, top, typ, m in msgs:
        if top == topic:
            old = m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
            m = type(m)(**{**{f: getattr(m, f) for f in m.__dataclass_fields__}, "header": _header(stamp(old))})
        out.append((t, top, typ, m))
    return out


def _audio_data(samples: np.ndarray):
    """audio_common AudioData: the chunk's samples as S16LE bytes."""
    return TS.types["audio_common_msgs/msg/AudioData"](data=np.frombuffer(samples.astype("<i2").tobytes(), np.uint8))


def _info(rate, channels=1, sample_format="S16LE", coding_format="wave"):
    return TS.types["audio_common_msgs/msg/AudioInfo"](
        channels=channels,
        sample_rate=rate,
        sample_format=sample_format,
        bitrate=rate * 16 * channels,
        coding_format=coding_format,
    )


# --- 1. audio_common audio --------------------------------------------------------------------


def _as_audio_common(msgs, kind):
    """The internal microphone's Int16MultiArray chunks as audio_common `kind` messages (48 kHz S16LE)."""
    out = []
    for t, topic, typ, m in msgs:
        if topic == INTERNAL:
            data = _audio_data(np.asarray(m.data))
            if kind == "AudioData":
                m = data
            elif kind == "AudioDataStamped":
                m = TS.types["audio_common_msgs/msg/AudioDataStamped"](header=_header(t), audio=data)
            else:
                audio = TS.types["audio_common_msgs/msg/Audio"](audio=data, info=_info(48000))
                m = TS.types["audio_common_msgs/msg/AudioStamped"](header=_header(t), audio=audio)
            typ = f"audio_common_msgs/msg/{kind}"
        out.append((t, topic, typ, m))
    return out


@pytest.mark.parametrize(
    "kind,table",
    [
        ("AudioData", {"format": "S16LE"}),  # format from the mapping
        ("AudioDataStamped", {"info_topic": "/minsound/audio_info"}),  # from an AudioInfo topic
        ("AudioStamped", {}),  # carried by every message
    ],
)
def test_audio_common_audio_is_read_bit_exact(tmp_path, kind, table):
    rec = recording()
    msgs = _as_audio_common(bag_messages(rec), kind)
    msgs.append((T0 - 0.2, "/minsound/audio_info", "audio_common_msgs/msg/AudioInfo", _info(48000)))
    mapping = _mapping(internal=table)
    if "format" not in table:
        del mapping["mics"]["internal"]["rate"]  # the rate comes from the AudioInfo
    a = ros_bag.import_bag(write_messages(tmp_path / "bag", msgs), mapping, TRIAL)
    check_fields(archive.validate(a), rec)


def test_raw_audio_takes_the_bags_only_audio_info_topic(tmp_path):
    rec = recording()
    msgs = _as_audio_common(bag_messages(rec), "AudioData")
    msgs.append((T0 - 0.2, "/minsound/audio_info", "audio_common_msgs/msg/AudioInfo", _info(48000)))
    mapping = _mapping(internal={})  # no format, no rate, no info_topic
    del mapping["mics"]["internal"]["rate"]
    a = ros_bag.import_bag(write_messages(tmp_path / "bag", msgs), mapping, TRIAL)
    check_fields(archive.validate(a), rec)
    assert a.meta["source"]["audio_info"] == {
        "internal": {"topic": "/minsound/audio_info", "chosen": "the bag's only AudioInfo topic"}
    }
    msgs.append(
        (T0 - 0.1, "/palm/audio_info", "audio_common_msgs/msg/AudioInfo", _info(48000))
    )  # two: whose is whose is unknown
    with pytest.raises(ros_bag.BagError, match=r"need a sample format"):
        ros_bag.import_bag(write_messages(tmp_path / "bag2", msgs), mapping, TRIAL)


def test_raw_audio_without_a_format_is_a_clear_error(tmp_path):
    rec = recording()
    bag = write_messages(tmp_path / "bag", _as_audio_common(bag_messages(rec), "AudioData"))
    with pytest.raises(
        ros_bag.BagError, match=r"/minsound/audio: sample_format: raw audio bytes \(uint8\[\]\) need a sample format"
    ):
        ros_bag.import_bag(bag, MAPPING, TRIAL)
    mapping = _mapping(internal={"format": "S32LE", "info_topic": "/info"})
    msgs = _as_audio_common(bag_messages(rec), "AudioData") + [
        (T0, "/info", "audio_common_msgs/msg/AudioInfo", _info(48000))
    ]
    with pytest.raises(
        ros_bag.BagError, match=r"mics\.internal\.format: 'S32LE' in the mapping, the bag's AudioInfo says 'S16LE'"
    ):
        ros_bag.import_bag(write_messages(tmp_path / "bag2", msgs), mapping, TRIAL)
    no_rate = _mapping()
    del no_rate["mics"]["external"]["rate"]
    with pytest.raises(ros_bag.BagError, match=r"mics\.external\.rate: missing, and no AudioInfo in the bag gives it"):
        ros_bag.import_bag(write_bag(tmp_path / "bag3", rec), no_rate, TRIAL)


# --- 2. no overwrite --------------------------------------------------------------------------


def test_an_existing_archive_is_not_overwritten_without_the_flag(tmp_path):
    (tmp_path / "map.toml").write_text(MAPPING_TOML)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "experiments.import_bag", "BAG", f"--map={tmp_path / 'map.toml'}", f"--out={out}"]
    first = write_bag(tmp_path / "bag1", recording(seed=1))
    second = write_bag(tmp_path / "bag2", recording(seed=2))
    done = subprocess.run([*cmd[:3], str(first), *cmd[4:]], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    target = out / "fabric04_day2_trial03_lab.npz"
    before = target.read_bytes()
    done = subprocess.run([*cmd[:3], str(second), *cmd[4:]], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [f"error: {target}: <file>: exists (pass --overwrite to replace it)"]
    assert target.read_bytes() == before
    done = subprocess.run([*cmd[:3], str(second), *cmd[4:], "--overwrite"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert target.read_bytes() != before


# --- 3. joint states --------------------------------------------------------------------------


def test_zero_joint_stamps_fall_back_to_receive_time_with_a_note(tmp_path):
    rec = recording()
    msgs = _restamp(bag_messages(rec), JOINTS, lambda t: 0.0)
    a = ros_bag.import_bag(write_messages(tmp_path / "bag", msgs), MAPPING, TRIAL)
    # joints received at their stamp + 2 ms: the latest at or before frame i is reading 4 + 2 i
    np.testing.assert_allclose(a.joints, rec["joints"][4 + 2 * np.arange(N_FRAMES)].astype(np.float32), rtol=1e-6)
    assert a.meta["import"]["clocks"]["joints"] == {
        "clock": "receive",
        "note": f"{len(rec['joint_t'])} of {len(rec['joint_t'])} header stamps are zero: placed by receive time",
    }


def _position_only(msgs):
    out = []
    for t, topic, typ, m in msgs:
        if topic == JOINTS:
            m = TS.types["sensor_msgs/msg/JointState"](
                header=m.header, name=m.name, position=m.position, velocity=np.zeros(0), effort=np.zeros(0)
            )
        out.append((t, topic, typ, m))
    return out


def test_position_only_joint_states_record_absent_fields(tmp_path):
    rec = recording()
    a = ros_bag.import_bag(write_messages(tmp_path / "bag", _position_only(bag_messages(rec))), MAPPING, TRIAL)
    path = archive.write_archive(tmp_path / "out" / archive.trial_filename(a.meta), a)
    back = archive.read_archive(path)
    assert back.meta["streams"]["joints"]["absent"] == ["velocity", "current"]
    assert archive.layout(back.meta).joint_fields_absent == ("velocity", "current")
    np.testing.assert_allclose(
        back.joints[..., 0], rec["joints"][5 + 2 * np.arange(N_FRAMES), :, 0].astype(np.float32), rtol=1e-6
    )
    assert np.isnan(back.joints[..., 1:]).all()  # never zeros
    # an absent field that holds values is refused
    fake = archive.TrialArchive(**{**back.__dict__, "joints": np.nan_to_num(back.joints)})
    with pytest.raises(
        archive.ArchiveError, match=r"joints': fields \['velocity', 'current'\] are recorded as absent but hold values"
    ):
        archive.validate(fake)


def test_a_field_that_comes_and_goes_is_an_error(tmp_path):
    msgs = bag_messages(recording())
    first = next(i for i, (_, topic, _, _) in enumerate(msgs) if topic == JOINTS)
    msgs[first : first + 1] = _position_only(msgs[first : first + 1])
    with pytest.raises(ros_bag.BagError, match=r"/joint_states: velocity: carried by 44 of 45 messages"):
        ros_bag.import_bag(write_messages(tmp_path / "bag", msgs), MAPPING, TRIAL)


# --- 4. clocks --------------------------------------------------------------------------------


def test_stamps_on_another_clock_are_an_error_unless_the_mapping_says_so(tmp_path):
    rec = recording()
    bag = write_messages(tmp_path / "bag", _restamp(bag_messages(rec), CAMERA, lambda t: t - 0.3))
    with pytest.raises(
        ros_bag.BagError,
        match=r"/minsight/image: header.stamp: 0\.301 s behind the bag's receive time "
        r"\(tolerance 0\.02 s\): the stamps are on another clock; set clock = \"device\"",
    ):
        ros_bag.import_bag(bag, MAPPING, TRIAL)
    for clock in ("receive", "device"):
        a = ros_bag.import_bag(bag, _mapping(camera={"clock": clock}), TRIAL)
        check_fields(a, rec)  # frames received 1 ms after their slot: the same steps
        assert a.meta["import"]["clocks"]["camera"] == {"clock": clock, "receive_minus_header_s": pytest.approx(0.301)}
    assert a.meta["import"]["clocks"]["joints"]["receive_minus_header_s"] == pytest.approx(0.002)


def test_device_clock_camera_is_shifted_onto_the_bag_clock(tmp_path):
    rec = recording()
    uptime = lambda t: t - T0 + 12.5  # noqa: E731  a camera stamping with its own uptime, its reference too
    bag = write_messages(tmp_path / "bag", _restamp(_restamp(bag_messages(rec), CAMERA, uptime), REFERENCE, uptime))
    with pytest.raises(ros_bag.BagError, match=r"header.stamp: 87\.501 s behind"):
        ros_bag.import_bag(bag, MAPPING, TRIAL)
    a = ros_bag.import_bag(bag, _mapping(camera={"clock": "device"}), TRIAL)
    check_fields(a, rec)
    assert a.meta["reference"]["times_s"] == pytest.approx([-0.5, -0.3])  # shifted as the camera's stamps are


# --- 5. a 30 fps camera -----------------------------------------------------------------------


def _thirty_fps(rec, drop=None):
    """The 50 Hz recording's frames replaced by frames at 30 fps over the same audio."""
    msgs = [m for m in bag_messages(rec) if m[1] != CAMERA]
    n = int(0.02 * (N_FRAMES - 1) * 30) + 1
    for i in range(n):
        if i != drop:
            t = T0 + i / 30
            img = TS.types["sensor_msgs/msg/Image"](
                header=_header(t),
                height=8,
                width=10,
                encoding="rgb8",
                is_bigendian=0,
                step=30,
                data=rec["frames"][i % N_FRAMES].ravel(),
            )
            msgs.append((t + 0.001, CAMERA, "sensor_msgs/msg/Image", img))
    return msgs, n


def test_thirty_fps_camera_sets_the_step_rate_not_frame_loss(tmp_path):
    rec = recording()
    msgs, n = _thirty_fps(rec)
    a = ros_bag.import_bag(write_messages(tmp_path / "bag", msgs), MAPPING, TRIAL)
    assert a.n_steps == n and a.meta["streams"]["steps"] == {"clock": "camera", "rate": 30}
    assert (
        a.meta["import"]["frame_gaps"] == [] and a.meta["import"]["step_rate_from"] == "median frame interval 33.33 ms"
    )
    folder = tmp_path / "data"
    archive.write_archive(folder / archive.trial_filename(a.meta), a)
    lost, _ = _thirty_fps(rec, drop=7)
    b = ros_bag.import_bag(write_messages(tmp_path / "bag2", lost), MAPPING, {**TRIAL, "trial": 4})
    assert [g["step"] for g in b.meta["import"]["frame_gaps"]] == [7]  # a real loss at 30 fps still shows
    archive.write_archive(folder / archive.trial_filename(b.meta), b)
    problems, _ = integrity.verify(folder, tmp_path / "ws")
    assert [str(p).split(": ")[1:3] for p in problems] == [["timestamps", "irregular"]]
    assert "step 7 comes 66.7 ms after step 6 (more than 1.5 periods of 33 ms" in str(problems[0])
    declared = ros_bag.import_bag(write_messages(tmp_path / "bag3", msgs), _mapping(camera={"rate": 29.97}), TRIAL)
    assert (
        archive.layout(declared.meta).step_rate == 29.97
        and declared.meta["import"]["step_rate_from"] == "mapping camera.rate"
    )


# --- 6-9. problems named precisely, all at once -----------------------------------------------


def test_every_problem_of_a_bag_is_listed_in_one_line(tmp_path):
    msgs = [m for m in bag_messages(recording()) if m[1] != CAMERA]
    msgs.append((T0, CAMERA, "std_msgs/msg/String", TS.types["std_msgs/msg/String"](data="not a frame")))
    bag = write_messages(tmp_path / "bag", msgs)
    mapping = _mapping(joints={"topic": "/hand/joints"}, external={"topic": "/palm/mic"})
    with pytest.raises(ros_bag.BagError) as e:
        ros_bag.import_bag(bag, mapping, TRIAL)
    assert str(e.value) == (
        f"{bag}: topics ['/hand/joints', '/palm/mic'] not in the bag (it has ['/joint_states', '/minsight/image', "
        "'/minsight/reference', '/minsound/audio', '/palm/audio']); /minsight/image: type "
        "std_msgs/msg/String, expected sensor_msgs/msg/Image "
        "or sensor_msgs/msg/CompressedImage"
    )


def test_metadata_qos_unlike_the_storage_still_reads_every_message(tmp_path):
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    never = QosTime(sec=0, nsec=0)
    qos = Qos(
        QosHistory.KEEP_LAST,
        10,
        QosReliability.RELIABLE,
        QosDurability.VOLATILE,
        never,
        never,
        QosLiveliness.AUTOMATIC,
        never,
        False,
    )
    rec = recording()
    bag = write_bag(tmp_path / "bag", rec, qos={JOINTS: [qos]})
    meta = bag / "metadata.yaml"
    text = meta.read_text()
    assert text.count("depth: 10") == 1
    meta.write_text(text.replace("depth: 10", "depth: 5"))  # the metadata spells the profile differently
    check_fields(ros_bag.import_bag(bag, MAPPING, TRIAL), rec)
    meta.write_text(text.replace("message_count: 45", "message_count: 47"))  # and counts more than are stored
    with pytest.raises(
        ros_bag.BagError, match=r"/joint_states: the bag's metadata counts 47 messages, 45 could be read"
    ):
        ros_bag.import_bag(bag, MAPPING, TRIAL)


def test_older_type_names_are_read(tmp_path):
    rec = recording()
    bag = write_bag(tmp_path / "bag", rec)
    meta = bag / "metadata.yaml"
    meta.write_text(meta.read_text().replace("sensor_msgs/msg/", "sensor_msgs/"))
    with sqlite3.connect(bag / "bag.db3") as db:
        db.execute("UPDATE topics SET type = replace(type, 'sensor_msgs/msg/', 'sensor_msgs/')")
        db.execute(
            "UPDATE message_definitions SET topic_type = replace(topic_type, 'sensor_msgs/msg/', 'sensor_msgs/')"
        )
    assert "type: sensor_msgs/Image" in meta.read_text()
    check_fields(ros_bag.import_bag(bag, MAPPING, TRIAL), rec)


def test_mapping_problems_name_the_mapping_file(tmp_path):
    path = tmp_path / "map.toml"
    path.write_text(
        MAPPING_TOML.replace(
            'topic = "/joint_states"', 'topic = "/joint_states"\nnames = ["a", "b", "a", "c", "d", "e"]'
        )
    )
    with pytest.raises(ros_bag.BagError, match=rf"^{path}: joints\.names: \['a'\] named more than once$"):
        mapping_file.load_mapping(path)
    path.write_text(
        MAPPING_TOML.replace('topic = "/joint_states"', 'topic = "/joint_states"\nnames = ["a"]\nclock = "gps"')
    )
    with pytest.raises(
        ros_bag.BagError, match=rf"^{path}: joints\.clock: must be one of .*; joints\.names: expected 6 names"
    ):
        mapping_file.load_mapping(path)


def test_8uc1_frames_read_as_mono8(tmp_path):
    rec = recording()
    gray = rec["frames"][..., 0]
    msgs = []
    for t, topic, typ, m in bag_messages(rec):
        if topic == CAMERA:
            i = int(round((m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 - T0) / 0.02))
            m = TS.types["sensor_msgs/msg/Image"](
                header=m.header, height=8, width=10, encoding="8UC1", is_bigendian=0, step=10, data=gray[i].ravel()
            )
        msgs.append((t, topic, typ, m))
    a = ros_bag.import_bag(write_messages(tmp_path / "bag", msgs), MAPPING, TRIAL)
    np.testing.assert_array_equal(a.images, np.repeat(gray[..., None], 3, axis=-1))


def test_folder_without_metadata_names_the_storage_file_to_give(tmp_path):
    rec = recording()
    bag = write_bag(tmp_path / "bag", rec, storage="mcap")
    (bag / "metadata.yaml").unlink()
    with pytest.raises(
        ros_bag.BagError,
        match=r"bag: metadata.yaml: missing \(a rosbag2 folder has one\); to read a storage "
        r"file without it give the file itself: bag\.mcap$",
    ):
        ros_bag.import_bag(bag, MAPPING, TRIAL)
    check_fields(ros_bag.import_bag(bag / "bag.mcap", MAPPING, TRIAL), rec)


def test_each_issue_case_is_one_line_on_the_command_line(tmp_path):
    (tmp_path / "map.toml").write_text(MAPPING_TOML)
    bag = write_messages(tmp_path / "bag", _restamp(bag_messages(recording()), CAMERA, lambda t: t - 0.3))
    cmd = [
        sys.executable,
        "-m",
        "experiments.import_bag",
        str(bag),
        f"--map={tmp_path / 'map.toml'}",
        f"--out={tmp_path / 'out'}",
    ]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "header.stamp: 0.301 s behind" in done.stderr
    assert not (tmp_path / "out").exists()


# --- a bag as a ROS 2 lab records it ----------------------------------------------------------

LAB_RATE, LAB_CHUNK, LAB_FPS, UPTIME_AT_T0 = 16000, 512, 30, 12.5  # audio_common at 16 kHz, 32 ms chunks
LAB_MAPPING = {
    "camera": {
        "topic": CAMERA,
        "clock": "device",
        "reference_topic": REFERENCE,
    },  # a camera driver stamping with the device's clock
    "mics": {
        "internal": {"topic": INTERNAL, "info_topic": "/minsound/audio_info"},
        "external": {"topic": EXTERNAL, "info_topic": "/palm/audio_info"},
    },
    "joints": {"topic": JOINTS},
    "trial": TRIAL,
}


def lab_messages(seed=0, seconds=1.0):
    """30 fps rgb8 frames stamped with the camera's uptime, received 4 ms later; two audio_common
    AudioData streams at 16 kHz S16LE (their AudioInfo published once, at the start) from 0.2 s
    before the first frame, each chunk received 1 ms after its last sample; position-only
    JointState (joint_state_publisher) at 50 Hz on the bag's clock, received 2 ms after the stamp;
    the camera's no-contact reference, one frame taken 0.3 s before the first and published once
    (latched: the bag receives it when it starts, 0.25 s before the first frame)."""
    rng = np.random.default_rng(seed)
    msgs = []
    for i in range(int(seconds * LAB_FPS)):
        t = T0 + i / LAB_FPS
        img = TS.types["sensor_msgs/msg/Image"](
            header=_header(t - T0 + UPTIME_AT_T0),
            height=8,
            width=10,
            encoding="rgb8",
            is_bigendian=0,
            step=30,
            data=rng.integers(0, 255, 240, dtype=np.uint8),
        )
        msgs.append((t + 0.004, CAMERA, "sensor_msgs/msg/Image", img))
    start = T0 - 0.2
    for topic in (INTERNAL, EXTERNAL):
        msgs.append((start, topic.replace("/audio", "/audio_info"), "audio_common_msgs/msg/AudioInfo", _info(LAB_RATE)))
        for k in range(int((seconds + 0.2) * LAB_RATE / LAB_CHUNK)):
            samples = rng.integers(-3000, 3000, LAB_CHUNK).astype(np.int16)
            msgs.append(
                (
                    start + (k + 1) * LAB_CHUNK / LAB_RATE + 0.001,
                    topic,
                    "audio_common_msgs/msg/AudioData",
                    _audio_data(samples),
                )
            )
    for k in range(int((seconds + 0.2) * 50)):
        t = start + k / 50
        js = TS.types["sensor_msgs/msg/JointState"](
            header=_header(t), name=NAMES, position=rng.normal(size=6), velocity=np.zeros(0), effort=np.zeros(0)
        )
        msgs.append((t + 0.002, JOINTS, "sensor_msgs/msg/JointState", js))
    ref = TS.types["sensor_msgs/msg/Image"](
        header=_header(UPTIME_AT_T0 - 0.3),
        height=8,
        width=10,
        encoding="rgb8",
        is_bigendian=0,
        step=30,
        data=rng.integers(0, 255, 240, dtype=np.uint8),
    )
    msgs.append((T0 - 0.25, REFERENCE, "sensor_msgs/msg/Image", ref))
    return sorted(msgs, key=lambda m: m[0])


def test_lab_bag_becomes_an_archive_read_archive_and_verify_accept(tmp_path):
    msgs = lab_messages()
    assert {m[1] for m in msgs} == {
        CAMERA,
        INTERNAL,
        EXTERNAL,
        JOINTS,
        REFERENCE,
        "/minsound/audio_info",
        "/palm/audio_info",
    }
    bag = write_messages(tmp_path / "bag", msgs, storage="mcap")
    with pytest.raises(
        RecordingImportError, match=r"/minsound/audio: rate: sample rate 16000 Hz, archives hold 48000 Hz"
    ):
        ros_bag.import_bag(bag, LAB_MAPPING, TRIAL)
    a = ros_bag.import_bag(bag, LAB_MAPPING, TRIAL, resample=True)
    folder = tmp_path / "data"
    back = archive.read_archive(archive.write_archive(folder / archive.trial_filename(a.meta), a))
    lay = archive.layout(back.meta)
    assert [m.rate for m in lay.mics] == [48000, 48000] and lay.step_rate == 30
    assert lay.joint_fields_absent == ("velocity", "current")
    assert back.meta["import"]["resampled"] == {
        t: {"from_hz": 16000, "to_hz": 48000, "method": "scipy.signal.resample_poly"} for t in (INTERNAL, EXTERNAL)
    }
    clocks = back.meta["import"]["clocks"]
    assert clocks["camera"] == {
        "clock": "device",
        "receive_minus_header_s": pytest.approx(T0 - UPTIME_AT_T0 + 0.004, abs=1e-6),
    }
    assert clocks["joints"]["clock"] == "header" and clocks["internal"] == {"clock": "receive"}
    np.testing.assert_allclose(np.diff(back.timestamps), 1 / LAB_FPS, atol=1e-6)
    assert back.n_steps >= 25 and back.meta["import"]["frame_gaps"] == []
    reference = next(m[3] for m in msgs if m[1] == REFERENCE)  # published once, its stamp on the camera's device clock
    np.testing.assert_array_equal(back.reference, np.asarray(reference.data).reshape(1, 8, 10, 3))
    assert back.meta["reference"] == {
        "how": f"imported: the one frame of {REFERENCE} (published once)",
        "session": "day2_lab",
        "times_s": [pytest.approx(-0.3, abs=1e-6)],
    }
    problems, _ = integrity.verify(folder, tmp_path / "ws")
    assert problems == []


def test_proprio_on_absent_joint_fields_is_a_one_line_error(tmp_path):
    from fabricjax.config import Config
    from fabricjax.sequences import data

    folder = tmp_path / "data"
    a = ros_bag.import_bag(
        write_messages(tmp_path / "bag", lab_messages(seconds=1.5)), LAB_MAPPING, TRIAL, resample=True
    )
    path = archive.write_archive(folder / archive.trial_filename(a.meta), a)
    config = Config(preset="smoke", seq_len=20, modalities=("internal", "proprio"))
    with pytest.raises(archive.ArchiveError) as e:
        data.load_sequences(config, folder, workdir=tmp_path / "ws", progress=False, workers=1, split_names=("train",))
    assert str(e.value) == (
        f"{path}: field 'joints': absent: the data has no proprio (proprioception) for the modalities internal, "
        "proprio; it has microphones: internal (48000 Hz, feeds internal), external (48000 Hz, feeds external); "
        "6 joints x angle [rad], velocity [rad/s] (not recorded), current [A] (not recorded); camera 8x10; "
        "steps at 30 Hz (camera clock) (choose rows or modalities it supports: internal, external, image, flow)"
    )
    sets = data.load_sequences(
        Config(preset="smoke", seq_len=20, modalities=("internal",)),
        folder,
        workdir=tmp_path / "ws",
        progress=False,
        workers=1,
        split_names=("train",),
    )
    assert len(sets["train"]) == a.n_steps // 20
