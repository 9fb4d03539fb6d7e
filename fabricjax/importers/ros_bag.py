"""A ROS 2 bag (sqlite3 or MCAP) read into timestamped streams (`read_bag`) and imported as a trial
archive (`import_bag`, aligned by `fabricjax.importers.alignment.align`).

Every problem the bag has (a missing topic, a topic of the wrong type, fewer messages than its
metadata counts, a message that cannot be decoded, clocks that disagree) is collected and reported
in one error, one line, rather than one per run. Types are checked before any message is read.

Clocks. Each stream is placed on the bag's receive clock, the one clock every message shares,
by the policy its mapping table names in `clock`:

    "receive"  the bag's receive time (the default for audio: audio messages of std_msgs carry no
               header; a chunk's time is taken as the time of its last sample)
    "header"   the header stamp (the default for the camera and the joints): it must agree with the
               receive time within `[clock] tolerance_s` (median of receive - stamp), else the
               stream is an error naming the offset, since a stamp on another clock would shift it
               against the audio
    "device"   header stamps from the device's own clock (their spacing is exact), shifted onto
               the receive clock by the median offset

Raw audio (AudioData, AudioDataStamped: bytes without a format) takes its format from the
mapping's `info_topic`; without one, from the bag's AudioInfo topic when the bag has exactly one,
which is logged and recorded (meta.source.audio_info).

The measured offset of every stamped stream is recorded (meta.import.clocks). A stream whose header
stamps are zero (a driver that never set them) is placed by receive time instead, with a note.

The session reference. The mapping's [camera] table must say where the camera's no-contact
reference comes from (`alignment.parse_reference`); a mapping that says nothing is an error:

    reference_topic = "/minsight/reference"   images as on the camera topic (Image or
                                              CompressedImage, the camera's size): every frame on
                                              it up to the trial's first camera frame, or the one
                                              frame of a topic published once (latched: recorded
                                              whenever the bag started)
    reference = "pre_contact"                 or: the trial's own first frames, only when asked
    reference_frames = 5                      how many (default 5), only with pre_contact

A reference frame's time is its header stamp placed as the camera's are (`_reference`), on the
trial's step clock in meta.reference.times_s; null where the stamps are unset or the camera is
placed by receive time (a latched frame is received when the bag starts, not when it was taken).
The mapping's [trial] table may name the trial's `session` (meta.reference.session).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
from absl import logging

from fabricjax.errors import UserError
from fabricjax.force_proxy import ForceProxy
from fabricjax.importers import ros_messages as rm
from fabricjax.importers.alignment import ImportedReference, ReferenceSource, align, parse_reference
from fabricjax.importers.streams import RecordingImportError, Stream, to_words
from fabricjax.store import archive

CLOCKS = ("receive", "header", "device")
DEFAULT_CLOCK = {"camera": "header", "joints": "header", "mic": "receive"}
# Placing a stream by header stamps that differ from the receive clock by more than one step
# (20 ms at 50 Hz) would move it by a step or more against the audio.
DEFAULT_CLOCK_TOLERANCE_S = 1.0 / archive.STEP_RATE
RAW_AUDIO_TYPES = ("audio_common_msgs/msg/AudioData", "audio_common_msgs/msg/AudioDataStamped")  # bytes, no format


class BagError(UserError):
    """Everything wrong with a bag or its mapping, in one line: `where: topic: field: problem; ...`."""

    def __init__(self, where, problems: list[str]):
        super().__init__(f"{where}: " + "; ".join(problems))


@dataclasses.dataclass
class Chunks:
    """One microphone as read: its chunks and their times on the receive clock."""

    topic: str
    rate: int
    times: list[float]
    chunks: list[np.ndarray]


@dataclasses.dataclass
class BagStreams:
    frame_times: np.ndarray
    images: np.ndarray
    mics: list[Chunks]  # in archive.MIC_NAMES order
    joint_times: np.ndarray
    joints: np.ndarray  # (N, 6, 3), NaN in fields the messages lack
    joint_fields_absent: list[str]
    step_rate: float | None  # declared in the mapping (camera.rate), else None: measured by align
    clocks: dict[str, Any]
    source: dict[str, Any]
    reference_source: ReferenceSource
    reference: ImportedReference | None  # the frames of reference_source's topic; None: pre_contact


def check_mapping(mapping: dict[str, Any], where) -> None:
    """The ROS-specific keys of a mapping (clocks, audio formats, joint names, the camera's
    reference), every problem at once."""
    problems = []
    try:
        if parse_reference(mapping["camera"], where, topic=True).name == mapping["camera"]["topic"]:
            problems.append(
                "camera.reference_topic: is camera.topic: the reference is the session's no-contact frames, "
                "not the trial's "
                '(set reference = "pre_contact" to use the trial\'s first frames)'
            )
    except RecordingImportError as e:
        problems.append(f"{e.field}: {e.problem}")

    def clock(table: dict, key: str) -> None:
        if "clock" in table and table["clock"] not in CLOCKS:
            problems.append(f"{key}.clock: must be one of {CLOCKS}, got {table['clock']!r}")

    clock(mapping["camera"], "camera")
    clock(mapping["joints"], "joints")
    rate = mapping["camera"].get("rate")
    if rate is not None and (isinstance(rate, bool) or not isinstance(rate, (int, float)) or rate <= 0):
        problems.append(f"camera.rate: must be a frame rate in Hz > 0, got {rate!r}")
    tolerance = mapping.get("clock", {}).get("tolerance_s", DEFAULT_CLOCK_TOLERANCE_S)
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float)) or tolerance < 0:
        problems.append(f"clock.tolerance_s: must be seconds >= 0, got {tolerance!r}")
    for m in archive.MIC_NAMES:
        mic = mapping["mics"][m]
        clock(mic, f"mics.{m}")
        if "format" in mic and mic["format"] not in rm.SAMPLE_FORMATS:
            problems.append(f"mics.{m}.format: must be one of {list(rm.SAMPLE_FORMATS)}, got {mic['format']!r}")
        for key, low in (("rate", 1), ("channels", 1), ("channel", 0)):
            value = mic.get(key)
            if value is not None and (not isinstance(value, int) or isinstance(value, bool) or value < low):
                problems.append(f"mics.{m}.{key}: must be an integer >= {low}, got {value!r}")
    names = mapping["joints"].get("names", list(archive.JOINT_NAMES))
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        problems.append(f"joints.names: must be a list of joint names, got {names!r}")
    elif len(names) != archive.N_JOINTS:
        problems.append(
            f"joints.names: expected {archive.N_JOINTS} names (archive order {list(archive.JOINT_NAMES)}), "
            f"got {len(names)}"
        )
    elif len(set(names)) != len(names):
        problems.append(f"joints.names: {sorted({n for n in names if names.count(n) > 1})} named more than once")
    if problems:
        raise BagError(where, problems)


def _place(
    name: str,
    stamps: list[float | None] | None,
    received: np.ndarray,
    policy: str,
    tolerance: float,
    problems: list[str],
    topic: str,
) -> tuple[np.ndarray, dict[str, Any]]:
    """A stream's times on the receive clock by its clock policy (module docstring), and what was
    done; `stamps` is None for a message type without a header."""
    record: dict[str, Any] = {"clock": policy}
    if stamps is None:
        if policy != "receive":
            problems.append(f'{name}.clock: {policy!r}, but {topic}\'s messages have no header: use "receive"')
        return received, record
    if not stamps:
        return received, record
    if any(s is None for s in stamps):
        zero = sum(s is None for s in stamps)
        if policy != "receive":
            record = {
                "clock": "receive",
                "note": f"{zero} of {len(stamps)} header stamps are zero: placed by receive time",
            }
        return received, record
    header = np.asarray(stamps, np.float64)
    offset = float(np.median(received - header))
    record["receive_minus_header_s"] = round(offset, 6)
    if policy == "receive":
        return received, record
    if policy == "device":
        return header + offset, record
    if abs(offset) > tolerance:
        problems.append(
            f"{topic}: header.stamp: {abs(offset):.3f} s {'behind' if offset > 0 else 'ahead of'} the bag's "
            f"receive time "
            f'(tolerance {tolerance} s): the stamps are on another clock; set clock = "device" in the mapping\'s '
            f'{name} table to shift them onto the bag\'s clock, or clock = "receive"'
        )
    return header, record


def _storage_connections(reader) -> list:
    """The connections as the storage files record them. A bag folder's reader matches messages to
    metadata.yaml's connections, QoS profiles included, and yields none for a topic whose profiles
    the metadata spells differently from the storage file; matched against the storage's own
    connections every message is read."""
    storages = getattr(reader.storage, "storages", None)
    return [c for s in storages for c in s.connections] if storages is not None else list(reader.connections)


def read_bag(bag: str | Path, mapping: dict[str, Any]) -> BagStreams:
    """Read the mapping's topics from `bag` (a rosbag2 folder, or one .mcap / .db3 file)."""
    try:
        from rosbags.rosbag2 import Reader
    except ModuleNotFoundError:
        raise UserError('reading bags needs the rosbags package: pip install -e ".[bags]"') from None
    check_mapping(mapping, "mapping")
    reference = parse_reference(mapping["camera"], "mapping", topic=True)
    bag = Path(bag)
    if not bag.exists():
        raise BagError(bag, ["<bag>: no such bag"])
    if bag.is_dir() and not (bag / "metadata.yaml").is_file():
        files = sorted(p.name for p in bag.iterdir() if p.suffix in (".mcap", ".db3"))
        hint = f"; to read a storage file without it give the file itself: {', '.join(files)}" if files else ""
        raise BagError(bag, [f"metadata.yaml: missing (a rosbag2 folder has one){hint}"])
    roles = {
        mapping["camera"]["topic"]: ("camera", rm.IMAGE_TYPES),
        mapping["joints"]["topic"]: ("joints", rm.JOINT_TYPES),
    }
    if reference.name is not None:
        roles[reference.name] = ("camera reference", rm.IMAGE_TYPES)
    for m in archive.MIC_NAMES:
        roles[mapping["mics"][m]["topic"]] = (m, rm.AUDIO_TYPES)
        if "info_topic" in mapping["mics"][m]:
            roles[mapping["mics"][m]["info_topic"]] = (f"{m} info", rm.AUDIO_INFO_TYPES)
    problems: list[str] = []
    try:
        with Reader(bag) as reader:
            declared: dict[str, int] = {}
            types: dict[str, set[str]] = {}
            for c in reader.connections:
                declared[c.topic] = declared.get(c.topic, 0) + c.msgcount
                types.setdefault(c.topic, set()).add(rm.normalize_type(c.msgtype))
            missing = [t for t in roles if t not in types]
            if missing:
                problems.append(f"topics {missing} not in the bag (it has {sorted(types)})")
            for topic, (_, expected) in roles.items():
                wrong = sorted(types.get(topic, set()) - set(expected))
                if wrong:
                    problems.append(f"{topic}: type {' and '.join(wrong)}, expected {' or '.join(expected)}")
            if problems:
                raise BagError(bag, problems)
            found = _only_audio_info(mapping, types)
            for m, topic in found.items():
                roles[topic] = (f"{m} info", rm.AUDIO_INFO_TYPES)
                logging.info(
                    "%s: the mapping names no info_topic for mics.%s (%s): using the bag's only AudioInfo topic, %s",
                    bag,
                    m,
                    mapping["mics"][m]["topic"],
                    topic,
                )
            storage = [c for c in _storage_connections(reader) if c.topic in roles]
            store = rm.typestore_for([*reader.connections, *storage])
            messages: dict[str, list] = {t: [] for t in roles}
            for conn, t_ns, raw in reader.messages(connections=storage):
                messages[conn.topic].append((t_ns * 1e-9, rm.normalize_type(conn.msgtype), raw))
    except UserError:
        raise
    except Exception as e:  # rosbags' own errors: an unreadable or unknown bag
        raise BagError(bag, [f"<bag>: cannot be read: {type(e).__name__}: {e}"]) from None
    for topic, got in messages.items():
        if len(got) != declared[topic]:
            problems.append(f"{topic}: the bag's metadata counts {declared[topic]} messages, {len(got)} could be read")
    decoded = {}
    for topic, got in messages.items():
        msgs = []
        for t, msgtype, raw in got:
            try:
                msgs.append((t, msgtype, store.deserialize_cdr(raw, msgtype)))
            except Exception as e:  # a definition that does not describe the bytes
                problems.append(f"{topic}: cannot be decoded as {msgtype}: {type(e).__name__}: {e}")
                break
        decoded[topic] = sorted(msgs, key=lambda x: x[0])
    tolerance = float(mapping.get("clock", {}).get("tolerance_s", DEFAULT_CLOCK_TOLERANCE_S))
    clocks: dict[str, Any] = {}
    cam = mapping["camera"]
    frame_times, images = _camera(decoded[cam["topic"]], cam, tolerance, problems, clocks)
    ref = (
        None
        if reference.name is None
        else _reference(decoded[reference.name], reference.name, frame_times, images, clocks.get("camera"), problems)
    )
    joint_times, joints, absent = _joints(
        decoded[mapping["joints"]["topic"]], mapping["joints"], tolerance, problems, clocks
    )
    info_topics = {m: mapping["mics"][m].get("info_topic", found.get(m)) for m in archive.MIC_NAMES}
    mics = [
        _mic(m, mapping["mics"][m], info_topics[m], decoded, tolerance, problems, clocks) for m in archive.MIC_NAMES
    ]
    if problems:
        raise BagError(bag, problems)
    return BagStreams(
        frame_times=frame_times,
        images=images,
        mics=mics,
        joint_times=joint_times,
        joints=joints,
        joint_fields_absent=absent,
        step_rate=cam.get("rate"),
        clocks=clocks,
        reference_source=reference,
        reference=ref,
        source={
            "kind": "ros2_bag",
            "path": str(bag),
            "topics": {
                "camera": cam["topic"],
                "joints": mapping["joints"]["topic"],
                **{m: mapping["mics"][m]["topic"] for m in archive.MIC_NAMES},
            },
            **(
                {"audio_info": {m: {"topic": t, "chosen": "the bag's only AudioInfo topic"} for m, t in found.items()}}
                if found
                else {}
            ),
        },
    )


def _only_audio_info(mapping: dict[str, Any], types: dict[str, set[str]]) -> dict[str, str]:
    """{microphone: the bag's AudioInfo topic} for each raw-audio microphone whose mapping names no
    info_topic, when the bag has exactly one AudioInfo topic (else none: which is whose is unknown)."""
    infos = [t for t, ts in types.items() if ts & set(rm.AUDIO_INFO_TYPES)]
    if len(infos) != 1:
        return {}
    return {
        m: infos[0]
        for m in archive.MIC_NAMES
        if "info_topic" not in mapping["mics"][m]
        and types.get(mapping["mics"][m]["topic"], set()) & set(RAW_AUDIO_TYPES)
    }


def _decode_each(msgs, decode, topic: str, problems: list[str]) -> list | None:
    """decode(msg) for every message; None after recording the first failure."""
    out = []
    for _, _, msg in msgs:
        try:
            out.append(decode(msg))
        except rm.DecodeError as e:
            problems.append(f"{topic}: {e.field}: {e.problem}")
            return None
        except AttributeError as e:  # a message definition other than the standard one
            problems.append(f"{topic}: {e}")
            return None
    return out


def _camera(msgs, table, tolerance, problems, clocks) -> tuple[np.ndarray, np.ndarray]:
    topic = table["topic"]
    frames = _decode_each(msgs, rm.decode_image, topic, problems)
    if not frames:
        return np.zeros(0), np.zeros((0, 1, 1, 3), np.uint8)
    if len({f.shape for f in frames}) > 1:
        problems.append(f"{topic}: data: frames of different sizes {sorted({f.shape for f in frames})}")
        return np.zeros(0), np.zeros((0, 1, 1, 3), np.uint8)
    received = np.array([t for t, _, _ in msgs])
    times, clocks["camera"] = _place(
        "camera",
        [rm.header_time(m) for _, _, m in msgs],
        received,
        table.get("clock", DEFAULT_CLOCK["camera"]),
        tolerance,
        problems,
        topic,
    )
    return times, np.stack(frames)


def _reference(
    msgs, topic: str, frame_times: np.ndarray, images: np.ndarray, camera_clock: dict | None, problems: list[str]
) -> ImportedReference | None:
    """The session's no-contact frames on `topic` (module docstring): every frame received up to
    the trial's first camera frame, or the one frame of a topic published once. Their times are
    their header stamps placed as the camera's are ("header": as they are, "device": shifted by the
    camera's measured offset), None where the stamps are unset or the camera is placed by receive
    time: a reference's receive time says when the bag got it, not when it was taken."""
    frames = _decode_each(msgs, rm.decode_image, topic, problems)
    if frames is None or camera_clock is None:  # a frame or the camera already a problem
        return None
    if not frames:
        problems.append(f"{topic}: no messages: the camera's reference topic holds no frame")
        return None
    if {f.shape for f in frames} != {images.shape[1:]}:
        problems.append(
            f"{topic}: data: frames of {sorted({f.shape[:2] for f in frames})} pixels, the camera's are "
            f"{images.shape[1:3]}: "
            "a reference is the camera's own frames, at their size"
        )
        return None
    stamps = [rm.header_time(m) for _, _, m in msgs]
    offset = camera_clock.get("receive_minus_header_s", 0.0) if camera_clock["clock"] == "device" else 0.0
    times = None if camera_clock["clock"] == "receive" or None in stamps else np.asarray(stamps, np.float64) + offset
    if len(frames) == 1:
        return ImportedReference(frames[0][None], times, f"imported: the one frame of {topic} (published once)")
    when = times if times is not None else np.array([t for t, _, _ in msgs])
    keep = np.flatnonzero(when <= frame_times.min())
    if not keep.size:
        problems.append(
            f"{topic}: none of its {len(frames)} frames comes before the trial's first camera frame "
            f"({frame_times.min():.3f} s): a no-contact reference is taken before the trial"
        )
        return None
    of = (
        f"{len(keep)} frame{'s' * (len(keep) > 1)}"
        if len(keep) <= archive.MAX_REFERENCE_FRAMES
        else f"the last {archive.MAX_REFERENCE_FRAMES} of {len(keep)} frames"
    )
    keep = keep[-archive.MAX_REFERENCE_FRAMES :]
    return ImportedReference(
        np.stack([frames[k] for k in keep]),
        None if times is None else times[keep],
        f"imported: {of} of {topic}, up to the trial's first camera frame",
    )


def _joints(msgs, table, tolerance, problems, clocks) -> tuple[np.ndarray, np.ndarray, list[str]]:
    topic = table["topic"]
    names = list(table.get("names", archive.JOINT_NAMES))
    rows = _decode_each(msgs, lambda m: rm.joint_row(m, names), topic, problems)
    if not rows:
        return np.zeros(0), np.zeros((0, archive.N_JOINTS, archive.N_JOINT_FIELDS)), []
    joints = np.stack(rows)
    absent = []
    for f, (field, ros_field) in enumerate(zip(archive.JOINT_FIELDS, ("position", "velocity", "effort"))):
        carried = int(np.count_nonzero(~np.isnan(joints[:, 0, f])))
        if carried == 0:
            absent.append(field)
        elif carried < len(joints):  # a field that comes and goes cannot be told from a lost reading
            problems.append(f"{topic}: {ros_field}: carried by {carried} of {len(joints)} messages")
    received = np.array([t for t, _, _ in msgs])
    times, clocks["joints"] = _place(
        "joints",
        [rm.header_time(m) for _, _, m in msgs],
        received,
        table.get("clock", DEFAULT_CLOCK["joints"]),
        tolerance,
        problems,
        topic,
    )
    return times, joints, absent


def _audio_format(name: str, table: dict, infos: list[dict], problems: list[str]) -> rm.AudioFormat | None:
    """The format the mapping gives, checked against the AudioInfo the bag carries (they must agree)."""
    where = f"mics.{name}"
    given = {"sample_format": table.get("format"), "channels": table.get("channels"), "rate": table.get("rate")}
    if infos:
        distinct = {tuple(sorted(i.items())) for i in infos}
        if len(distinct) > 1:
            problems.append(
                f"{table['topic']}: audio info: the format changes during the recording ({len(distinct)} "
                f"different AudioInfo)"
            )
            return None
        info = infos[0]
        if info["coding_format"].lower() not in ("", "wave", "pcm"):
            problems.append(
                f"{table['topic']}: coding_format: {info['coding_format']!r} audio is compressed; record "
                "audio_common with coding_format wave (raw samples)"
            )
            return None
        if info["sample_format"] not in rm.SAMPLE_FORMATS:
            problems.append(
                f"{table['topic']}: sample_format: {info['sample_format']!r} not supported "
                f"({', '.join(rm.SAMPLE_FORMATS)})"
            )
            return None
        for key, value in given.items():
            if value is not None and value != info[key]:
                problems.append(
                    f"{where}.{key if key != 'sample_format' else 'format'}: {value!r} in the mapping, "
                    f"the bag's AudioInfo says {info[key]!r}"
                )
                return None
        given = {k: info[k] for k in given}
    channels = given["channels"] or 1
    channel = table.get("channel", 0)
    if channels > 1 and "channel" not in table:
        problems.append(
            f"{where}.channel: missing: the audio has {channels} interleaved channels; name the one this "
            f"microphone is (0-{channels - 1})"
        )
        return None
    if channel >= channels:
        problems.append(f"{where}.channel: {channel}, but the audio has {channels} channels")
        return None
    return rm.AudioFormat(given["sample_format"], channels, channel, given["rate"])


def _mic(name, table, info_topic, decoded, tolerance, problems, clocks) -> Chunks:
    """Microphone `name` (mapping table `table`), its format from `info_topic`'s AudioInfo where given."""
    topic = table["topic"]
    msgs = decoded[topic]
    infos = [rm.info_fields(m) for _, _, m in decoded.get(info_topic, [])]
    try:
        embedded = [rm.audio_payload(m, t) for _, t, m in msgs]
        infos += [rm.info_fields(i) for _, i in embedded if i is not None]
    except AttributeError as e:  # a message definition other than the standard one
        problems.append(f"{topic}: {e}")
        return Chunks(topic, 0, [], [])
    fmt = _audio_format(name, table, infos, problems)
    if fmt is None or not embedded:
        return Chunks(topic, int(table.get("rate") or 0), [], [])
    chunks = []
    for payload, _ in embedded:
        try:
            chunks.append(rm.decode_audio(payload, fmt))
        except rm.DecodeError as e:
            problems.append(f"{topic}: {e.field}: {e.problem}")
            return Chunks(topic, fmt.rate or 0, [], [])
    stamped = all(t in rm.STAMPED_AUDIO_TYPES for _, t, _ in msgs)
    stamps = [rm.header_time(m) for _, _, m in msgs] if stamped else None
    received = np.array([t for t, _, _ in msgs])
    times, clocks[name] = _place(
        f"mics.{name}", stamps, received, table.get("clock", DEFAULT_CLOCK["mic"]), tolerance, problems, topic
    )
    if fmt.rate is None:
        problems.append(f"mics.{name}.rate: missing, and no AudioInfo in the bag gives it (set rate, or info_topic)")
        return Chunks(topic, 0, [], [])
    return Chunks(topic, fmt.rate, list(times), chunks)


def import_bag(
    bag: str | Path,
    mapping: dict[str, Any],
    trial: dict[str, Any],
    *,
    resample: bool = False,
) -> archive.TrialArchive:
    """Read a ROS 2 bag (sqlite3 or MCAP folder, or one storage file) with `rosbags`, each stream
    placed on the bag's receive clock by the mapping's clock policy (module docstring), and
    align it (`fabricjax.importers.alignment`)."""
    rec = read_bag(bag, mapping)
    mics = [
        Stream.from_chunks(c.topic, c.rate, c.times, [to_words(x, c.topic, "data") for x in c.chunks]) for c in rec.mics
    ]
    return align(
        frame_times=rec.frame_times,
        images=rec.images,
        mics=mics,
        joint_times=rec.joint_times,
        joints=rec.joints,
        trial=trial,
        source=rec.source,
        reference=rec.reference_source,
        named=rec.reference,
        resample=resample,
        force_gain=float(mapping.get("force", {}).get("gain", ForceProxy.gain)),
        force_deadband=float(mapping.get("force", {}).get("deadband", ForceProxy.deadband)),
        step_rate=rec.step_rate,
        joint_fields_absent=rec.joint_fields_absent,
        clocks=rec.clocks,
    )
