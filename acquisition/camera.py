"""Minsight's camera through OpenCV, preprocessed as the Minsight sensor code does, and the force proxy.

Minsight streams 1280x960 frames (V4L2, 60 fps); its software keeps columns 160..1120, flips both
axes and resizes to 410x308 (W x H). The closing of the grasp needs a contact force: Minsight's own
force network (reference-difference and gradient images -> 3x40x40 force map) is not available
here, so `ForceProxy` is a calibrated proxy for its scalar normal force: the mean absolute
difference to a no-contact reference image, mapped linearly to newtons. It is only meant to detect
the 0.1 N grasp threshold, not to replace the network.
"""

from __future__ import annotations

import dataclasses
import time

import cv2
import numpy as np

from fabricjax import archive

RAW_SIZE = (1280, 960)  # W, H
# Minsight's camera node reads and discards 20 frames after opening the camera (the sensor's
# warm-up: exposure and white balance settle), then saves the next frame as its no-contact
# reference (martius-lab/Minsight-sensor, Code/minsight_runner_ros/src/minsight_sensor/minsight_sensor/camera.py).
WARMUP_FRAMES = 20
CROP_COLUMNS = (160, 1120)
IMAGE_SIZE = archive.MINSIGHT_SIZE  # H, W (archive order)


class CameraError(RuntimeError):
    """The camera could not be opened or stopped delivering frames."""


def preprocess(raw: np.ndarray) -> np.ndarray:
    """1280x960 BGR -> 308x410 RGB, exactly Minsight's crop, double flip and resize."""
    crop = raw[:, CROP_COLUMNS[0] : CROP_COLUMNS[1]]
    small = cv2.resize(crop, (IMAGE_SIZE[1], IMAGE_SIZE[0]), interpolation=cv2.INTER_AREA)
    return cv2.cvtColor(cv2.flip(small, -1), cv2.COLOR_BGR2RGB)  # flipping after the resize is cheaper


class Camera:
    """A `cv2.VideoCapture` on a device index or a path. A frame identical to the previous one is a
    repeated buffer, i.e. the sensor dropped a frame: it is counted, and kept so the step has an image."""

    def __init__(self, source: int | str, *, retries: int = 3):
        self.source, self.retries, self.dropped = source, retries, 0
        self.cap = cv2.VideoCapture(source)
        if not self.cap.isOpened():
            raise CameraError(f"camera {source!r}: cannot open")
        if isinstance(source, int):
            self.cap.set(cv2.CAP_PROP_FRAME_WIDTH, RAW_SIZE[0])
            self.cap.set(cv2.CAP_PROP_FRAME_HEIGHT, RAW_SIZE[1])
            self.cap.set(cv2.CAP_PROP_FPS, 60)
            self.cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)  # the newest frame, not a queued one
        self._last: np.ndarray | None = None

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

    def meta(self, t0: float) -> dict:
        """`meta.reference` of a trial whose step clock started at perf_counter `t0`."""
        times = None if self.taken_at is None else [t - t0 for t in self.taken_at]
        return {"how": self.how, "session": self.session, "times_s": times}


def take_reference(camera: "Camera", session: str, n_frames: int = 1, warmup: int = WARMUP_FRAMES) -> Reference:
    """The reference as Minsight's camera node takes it: `warmup` frames read and discarded, then
    `n_frames` frames with the fingers open (no contact), before the first closing. Frames the
    sensor repeated during the warm-up are not counted as the trial's dropped frames."""
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


@dataclasses.dataclass
class ForceProxy:
    """force = gain * max(0, mean|image - reference| - deadband), in newtons.

    `deadband` absorbs sensor noise; `gain` comes from `calibrate` against known forces (a load
    cell on hardware, the simulator's force for simulated devices)."""

    reference: np.ndarray
    gain: float = 0.05
    deadband: float = 0.5

    def difference(self, image: np.ndarray) -> float:
        return float(cv2.absdiff(image, self.reference).mean())

    def __call__(self, image: np.ndarray) -> float:
        return self.gain * max(0.0, self.difference(image) - self.deadband)

    @classmethod
    def calibrate(cls, reference: np.ndarray, images, forces) -> "ForceProxy":
        """Least-squares line force = gain * (difference - deadband) through frames of known force,
        e.g. no-contact frames (0 N) and frames of the closing ramp up to the grasp."""
        d = np.array([float(cv2.absdiff(im, reference).mean()) for im in images])
        f = np.asarray(forces, float)
        if len(np.unique(f)) < 2:
            raise ValueError("calibration needs frames of at least two different known forces")
        slope, intercept = np.polyfit(d, f, 1)
        if slope <= 0:
            raise ValueError(f"calibration failed: force does not grow with the image difference (slope {slope:.3g})")
        return cls(reference=reference, gain=float(slope), deadband=float(-intercept / slope))
