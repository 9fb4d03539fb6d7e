"""ROS 2 messages as the bag importer reads them: the types it accepts per stream, the typestore
that decodes them, and the decoding of frames, audio chunks and joint states.

audio_common's messages are not in rosbags' stock typestores; `AUDIO_COMMON_MSGS` holds their
.msg definitions, registered next to ROS 2 Humble's types (a bag that stores its own definitions,
as MCAP always does, is decoded with those). Sources of the definitions:

* AudioData, AudioDataStamped, AudioInfo: ros-drivers/audio_common, ROS 2 branch,
  audio_common_msgs/msg/{AudioData,AudioDataStamped,AudioInfo}.msg (AudioData is the raw
  `uint8[] data` of the capture; its sample format, channel count and rate are in AudioInfo,
  published on a separate topic, e.g. /audio/audio_info).
* Audio, AudioStamped: audio_common's ROS 2 branch, audio_common_msgs/msg/Audio.msg
  (`AudioData audio`, `AudioInfo info`: a chunk carrying its own format) and AudioStamped.msg
  (`std_msgs/Header header`, `Audio audio`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import cv2
import numpy as np

from fabricjax.store import archive

AUDIO_COMMON_MSGS = {
    "audio_common_msgs/msg/AudioData": "uint8[] data",
    "audio_common_msgs/msg/AudioDataStamped": "std_msgs/Header header\naudio_common_msgs/AudioData audio",
    "audio_common_msgs/msg/AudioInfo": (
        "uint8 channels\nuint32 sample_rate\nstring sample_format\nuint32 bitrate\nstring coding_format"
    ),
    "audio_common_msgs/msg/Audio": "audio_common_msgs/AudioData audio\naudio_common_msgs/AudioInfo info",
    "audio_common_msgs/msg/AudioStamped": "std_msgs/Header header\naudio_common_msgs/Audio audio",
}

IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
JOINT_TYPES = ("sensor_msgs/msg/JointState",)
AUDIO_TYPES = (
    "std_msgs/msg/Int16MultiArray",
    "std_msgs/msg/Int32MultiArray",
    "audio_common_msgs/msg/AudioData",
    "audio_common_msgs/msg/AudioDataStamped",
    "audio_common_msgs/msg/AudioStamped",
)
AUDIO_INFO_TYPES = ("audio_common_msgs/msg/AudioInfo",)
STAMPED_AUDIO_TYPES = ("audio_common_msgs/msg/AudioDataStamped", "audio_common_msgs/msg/AudioStamped")

# Sample formats of raw (uint8[]) audio: GStreamer's names, which audio_common's AudioInfo uses.
# int16 words move to the top 16 of the SPH0645's 18 valid bits, int32 words are kept (`to_words`).
SAMPLE_FORMATS = {"S16LE": np.dtype("<i2"), "S32LE": np.dtype("<i4")}
# Image encodings by channel count; 8UC1 / 8UC3 are OpenCV's names for the mono8 / bgr8 layouts.
IMAGE_ENCODINGS = {"rgb8": 3, "bgr8": 3, "mono8": 1, "8UC1": 1, "8UC3": 3}
BGR_ENCODINGS = ("bgr8", "8UC3")


def normalize_type(name: str) -> str:
    """`pkg/msg/Name` for the older `pkg/Name` spelling some bags' metadata uses."""
    parts = name.split("/")
    return f"{parts[0]}/msg/{parts[1]}" if len(parts) == 2 else name


def typestore_for(connections) -> Any:
    """A typestore holding ROS 2 Humble's types, audio_common's and every definition the bag stores
    (the bag's win: they describe what was recorded), under the `pkg/msg/Name` spelling."""
    from rosbags.interfaces import MessageDefinitionFormat
    from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

    types = dict(get_typestore(Stores.ROS2_HUMBLE).fielddefs)
    for name, text in AUDIO_COMMON_MSGS.items():
        types.update(get_types_from_msg(text, name))
    for conn in connections:
        if conn.msgdef.format == MessageDefinitionFormat.MSG:
            types.update(get_types_from_msg(conn.msgdef.data, normalize_type(conn.msgtype)))
        elif conn.msgdef.format == MessageDefinitionFormat.IDL:
            sep = "=" * 80 + "\n"
            for idl in conn.msgdef.data.split(sep)[1:] if conn.msgdef.data.startswith(sep) else [conn.msgdef.data]:
                types.update(get_types_from_idl(idl.split("\n", 1)[1] if idl.startswith("IDL: ") else idl))
    store = get_typestore(Stores.EMPTY)
    store.register(types)
    return store


def header_time(msg) -> float | None:
    """The header stamp in seconds; None for a zero stamp (a driver that never set it)."""
    stamp = msg.header.stamp
    return None if stamp.sec == 0 and stamp.nanosec == 0 else stamp.sec + stamp.nanosec * 1e-9


class DecodeError(ValueError):
    """A message that cannot be decoded: `field` and `problem` name what is wrong."""

    def __init__(self, field: str, problem: str):
        self.field, self.problem = field, problem
        super().__init__(f"{field}: {problem}")


def decode_image(msg) -> np.ndarray:
    """RGB uint8 from sensor_msgs/Image (`IMAGE_ENCODINGS`) or CompressedImage (any format OpenCV reads)."""
    if hasattr(msg, "format"):
        img = cv2.imdecode(np.asarray(msg.data, np.uint8), cv2.IMREAD_COLOR)
        if img is None:
            raise DecodeError("data", f"compressed frame ({msg.format}) cannot be decoded")
        return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    if msg.encoding not in IMAGE_ENCODINGS:
        raise DecodeError("encoding", f"image encoding {msg.encoding!r} not supported ({', '.join(IMAGE_ENCODINGS)})")
    c = IMAGE_ENCODINGS[msg.encoding]
    data = np.asarray(msg.data, np.uint8)
    if msg.step < msg.width * c or data.size != msg.height * msg.step:
        raise DecodeError(
            "data", f"{data.size} bytes for {msg.height} rows of step {msg.step} ({msg.width} x {c} channels)"
        )
    img = data.reshape(msg.height, msg.step)[:, : msg.width * c].reshape(msg.height, msg.width, c)
    if msg.encoding in BGR_ENCODINGS:
        return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    return cv2.cvtColor(img, cv2.COLOR_GRAY2RGB) if c == 1 else img.copy()


@dataclasses.dataclass(frozen=True)
class AudioFormat:
    """How a chunk's samples are laid out: from the mapping, an AudioInfo topic or the message."""

    sample_format: str | None  # a `SAMPLE_FORMATS` key; None for typed arrays (Int16/Int32MultiArray)
    channels: int
    channel: int  # the one this microphone is
    rate: int | None


def info_fields(info) -> dict[str, Any]:
    """The fields of an audio_common AudioInfo that say how to read the bytes."""
    return {
        "sample_format": str(info.sample_format),
        "channels": int(info.channels),
        "rate": int(info.sample_rate),
        "coding_format": str(info.coding_format),
    }


def audio_payload(msg, msgtype: str) -> tuple[np.ndarray, Any]:
    """The chunk's samples (typed array or raw bytes) and the AudioInfo it carries (or None)."""
    if msgtype.startswith("std_msgs/"):
        return np.asarray(msg.data), None
    if msgtype == "audio_common_msgs/msg/AudioData":
        return np.asarray(msg.data, np.uint8), None
    if msgtype == "audio_common_msgs/msg/AudioDataStamped":
        return np.asarray(msg.audio.data, np.uint8), None
    return np.asarray(msg.audio.audio.data, np.uint8), msg.audio.info  # AudioStamped


def decode_audio(payload: np.ndarray, fmt: AudioFormat) -> np.ndarray:
    """One microphone's samples of a chunk: raw bytes read as `fmt.sample_format`, interleaved
    channels split, `fmt.channel` kept."""
    if payload.dtype == np.uint8:
        if fmt.sample_format is None:
            raise DecodeError(
                "sample_format",
                "raw audio bytes (uint8[]) need a sample format: give format in the "
                "mapping or an AudioInfo topic as info_topic",
            )
        dtype = SAMPLE_FORMATS[fmt.sample_format]
        frame = dtype.itemsize * fmt.channels
        if payload.size % frame:
            raise DecodeError(
                "data",
                f"{payload.size} bytes is not a whole number of {fmt.channels}-channel {fmt.sample_format} frames",
            )
        payload = payload.view(dtype).astype(dtype.newbyteorder("="))
    if payload.size % fmt.channels:
        raise DecodeError("data", f"{payload.size} samples is not a whole number of {fmt.channels}-channel frames")
    return payload.reshape(-1, fmt.channels)[:, fmt.channel]


def joint_row(msg, names: list[str]) -> np.ndarray:
    """(6, 3) angle, velocity, current (JointState effort) in the archive's joint order; a field
    the message does not carry (an empty array: `joint_state_publisher` sends positions only) is NaN."""
    index = {n: i for i, n in enumerate(msg.name)}
    missing = [n for n in names if n not in index]
    if missing:
        raise DecodeError("name", f"joints {missing} not in the message (it has {list(msg.name)})")
    row = np.full((archive.N_JOINTS, archive.N_JOINT_FIELDS), np.nan)
    for f, (field, values) in enumerate(
        zip(("position", "velocity", "effort"), (msg.position, msg.velocity, msg.effort))
    ):
        if len(values) == 0:
            continue
        if len(values) != len(msg.name):
            raise DecodeError(field, f"{len(values)} values for {len(msg.name)} joint names")
        row[:, f] = np.asarray(values, np.float64)[[index[n] for n in names]]
    return row
