"""Minsight's camera through OpenCV, preprocessed as the Minsight sensor code does, and its session
reference.

Minsight streams 1280x960 frames (V4L2, 60 fps); its software keeps columns 160..1120, flips both
axes and resizes to 410x308 (W x H). The closing of the grasp reads its contact force from these
frames against the reference (`fabricjax.force_proxy.ForceProxy`).

A no-contact reference is only a reference while the camera's exposure and white balance stay
where they were when it was taken, so a device camera is put on fixed ones (`controls_for`) and reads
each back: a camera that refuses one still records, and says so in one logged line.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time

import cv2
import numpy as np
from absl import logging

from fabricjax.store import archive

RAW_SIZE = (1280, 960)  # W, H
# Minsight's camera node reads and discards 20 frames after opening the camera (the sensor's
# warm-up: exposure and white balance settle), then saves the next frame as its no-contact
# reference (martius-lab/Minsight-sensor, Code/minsight_runner_ros/src/minsight_sensor/minsight_sensor/camera.py).
WARMUP_FRAMES = 20
CROP_COLUMNS = (160, 1120)
IMAGE_SIZE = archive.MINSIGHT_SIZE  # H, W (archive order)

# Fixed exposure and white balance, set in this order (a V4L2 driver ignores or refuses a manual
# exposure or colour temperature while the matching automatic control is on).
# CAP_PROP_AUTO_EXPOSURE is V4L2's exposure_auto menu, passed through as is by OpenCV's V4L2 backend
# (modules/videoio/src/cap_v4l.cpp, capPropertyToV4L2: V4L2_CID_EXPOSURE_AUTO): 1 is
# V4L2_EXPOSURE_MANUAL (3, aperture priority, is the usual UVC default). Only with the environment
# variable OPENCV_VIDEOIO_V4L_RANGE_NORMALIZED on (default off, OpenCV's environment-variable
# reference) does the backend map that menu's 0..4 onto [0, 1), making manual 0.25. Other backends
# document no value; they get 0.25, the normalised value OpenCV 3.x used everywhere, and the
# read-back says whether it took.
MANUAL_EXPOSURE_V4L2 = 1.0
MANUAL_EXPOSURE_NORMALISED = 0.25
# Minsight's own camera node sets this exposure (cap.set(cv2.CAP_PROP_EXPOSURE, 156.0), same file as
# WARMUP_FRAMES): V4L2's exposure_time_absolute in 100 us units, 15.6 ms, inside a 60 fps frame (16.7 ms).
EXPOSURE = 156.0
# Minsight's node tries to turn automatic white balance off (it passes -1); 0 is off for V4L2's
# white_balance_automatic. The colour temperature then used is 4600 K, the factory default of the
# white_balance_temperature control (2800..6500 K) that UVC cameras commonly list (v4l2-ctl
# --list-ctrls): the colours stay those the automatic balance starts from, and no longer re-adapt to
# the image as contact deforms the shell, which would move them away from the reference's.
WB_TEMPERATURE = 4600.0


def manual_exposure(backend: str) -> float:
    """The CAP_PROP_AUTO_EXPOSURE value that means manual exposure on OpenCV backend `backend`."""
    normalised = os.environ.get("OPENCV_VIDEOIO_V4L_RANGE_NORMALIZED", "").strip().lower() in ("1", "true", "on", "yes")
    return MANUAL_EXPOSURE_V4L2 if backend == "V4L2" and not normalised else MANUAL_EXPOSURE_NORMALISED


def controls_for(backend: str) -> tuple[tuple[str, int, float], ...]:
    """(name, OpenCV property, value asked) of each fixed control, in the order they are set."""
    return (
        ("auto_exposure", cv2.CAP_PROP_AUTO_EXPOSURE, manual_exposure(backend)),
        ("exposure", cv2.CAP_PROP_EXPOSURE, EXPOSURE),
        ("auto_wb", cv2.CAP_PROP_AUTO_WB, 0.0),
        ("wb_temperature", cv2.CAP_PROP_WB_TEMPERATURE, WB_TEMPERATURE),
    )


class CameraError(RuntimeError):
    """The camera could not be opened or stopped delivering frames."""


def preprocess(raw: np.ndarray) -> np.ndarray:
    """1280x960 BGR -> 308x410 RGB, exactly Minsight's crop, double flip and resize."""
    crop = raw[:, CROP_COLUMNS[0] : CROP_COLUMNS[1]]
    small = cv2.resize(crop, (IMAGE_SIZE[1], IMAGE_SIZE[0]), interpolation=cv2.INTER_AREA)
    return cv2.cvtColor(cv2.flip(small, -1), cv2.COLOR_BGR2RGB)  # flipping after the resize is cheaper


class Camera:
    """A `cv2.VideoCapture` on a device index or a path. A frame identical to the previous one is a
    repeated buffer, i.e. the sensor dropped a frame: it is counted, and kept so the step has an image.

    A device gets fixed exposure and white balance (`controls_for`); `controls` holds, for each, the
    value asked and the value the camera reads back (None where it reads no number), for the
    trial's meta.source. A file has no controls: `controls` is empty."""

    def __init__(self, source: int | str, *, retries: int = 3):
        self.source, self.retries, self.dropped = source, retries, 0
        self.controls: dict[str, dict[str, float | None]] = {}
        self.cap = cv2.VideoCapture(source)
        if not self.cap.isOpened():
            raise CameraError(f"camera {source!r}: cannot open")
        if isinstance(source, int):
            self.cap.set(cv2.CAP_PROP_FRAME_WIDTH, RAW_SIZE[0])
            self.cap.set(cv2.CAP_PROP_FRAME_HEIGHT, RAW_SIZE[1])
            self.cap.set(cv2.CAP_PROP_FPS, 60)
            self.cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)  # the newest frame, not a queued one
            self._fix_controls()
        self._last: np.ndarray | None = None

    def _fix_controls(self) -> None:
        """Set each fixed control and read it back; one warning line per control the camera refuses
        (set fails, or it reads something else), and recording goes on with what it reads."""
        try:
            backend = self.cap.getBackendName()
        except cv2.error:
            backend = "unknown"
        for name, prop, asked in controls_for(backend):
            accepted = bool(self.cap.set(prop, asked))
            value = float(self.cap.get(prop))
            read = value if math.isfinite(value) else None
            self.controls[name] = {"asked": asked, "read": read}
            if not accepted or read is None or not math.isclose(read, asked, rel_tol=1e-6, abs_tol=1e-6):
                logging.warning(
                    "camera %r (%s): %s not fixed: asked %g, %s, reads %s; recording goes on with the camera's value",
                    self.source,
                    backend,
                    name,
                    asked,
                    "set accepted" if accepted else "set refused",
                    "no number" if read is None else f"{read:g}",
                )

    def read(self) -> np.ndarray:
        """The next frame, preprocessed to 308x410x3 RGB uint8."""
        for _ in range(self.retries + 1):
            ok, raw = self.cap.read()
            if ok:
                break
        else:
            raise CameraError(
                f"camera {self.source!r}: no frame after {self.retries + 1} reads (stream ended or unplugged)"
            )
        if raw.shape[:2] != (RAW_SIZE[1], RAW_SIZE[0]):
            raise CameraError(
                f"camera {self.source!r}: frame {raw.shape[1]}x{raw.shape[0]}, expected {RAW_SIZE[0]}x{RAW_SIZE[1]}"
            )
        image = preprocess(raw)
        if self._last is not None and np.array_equal(image, self._last):
            self.dropped += 1
        self._last = image
        return image

    def close(self) -> None:
        self.cap.release()


@dataclasses.dataclass(frozen=True)
class Reference:
    """A session's no-contact frames, what Minsight's software reads every frame against, and when
    they were taken (`time.perf_counter()` of each), for the trial archive (`meta(t0)`)."""

    frames: np.ndarray  # (R, H, W, 3) uint8
    session: str
    how: str
    taken_at: tuple[float, ...] | None  # perf_counter of each frame; None: not known (simulated)

    def mean_frame(self) -> np.ndarray:
        """(H, W, 3) uint8: the frames' mean, rounded to the nearest grey level, as
        `fabricjax.features.images.session_difference` reads several reference frames."""
        return np.rint(self.frames.astype(np.float32).mean(0)).astype(np.uint8)

    def meta(self, t0: float) -> dict:
        """`meta.reference` of a trial whose step clock started at perf_counter `t0`."""
        times = None if self.taken_at is None else [t - t0 for t in self.taken_at]
        return {"how": self.how, "session": self.session, "times_s": times}


def take_reference(
    camera: "Camera", session: str, n_frames: int = archive.REFERENCE_FRAMES, warmup: int = WARMUP_FRAMES
) -> Reference:
    """The reference as Minsight's camera node takes it: `warmup` frames read and discarded, then
    `n_frames` frames with the fingers open (no contact), before the first closing. Minsight's node
    keeps one frame; several are averaged where they are read (`Reference.mean_frame`), so the
    reference carries less of one frame's sensor noise. Frames the sensor repeated during the
    warm-up are not counted as the trial's dropped frames."""
    for _ in range(warmup):
        camera.read()
    frames, times = [], []
    for _ in range(n_frames):
        frames.append(camera.read())
        times.append(time.perf_counter())
    camera.dropped = 0
    how = (
        f"recorded: {n_frames} no-contact frame{'s' * (n_frames > 1)} after {warmup} warm-up frames, fingers "
        f"open, before the first closing"
    )
    return Reference(np.stack(frames), session, how, tuple(times))
