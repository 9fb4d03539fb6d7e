"""Minsight's camera on fixed exposure and white balance, read back, and its session reference of
`archive.REFERENCE_FRAMES` frames, against a fake `cv2.VideoCapture` (no camera is needed)."""

import logging

import cv2
import numpy as np
import pytest

from acquisition import camera
from fabricjax.store import archive
from tests.helpers import CountingCamera


class _FakeCapture:
    """An open V4L2 device that stores what is set and reads it back, except the properties in
    `refuse` (set returns False, the read-back keeps the camera's own value) and in `clamp` (set
    returns True, as OpenCV's V4L2 backend does when the driver clamps, and reads the clamped value)."""

    refuse: dict[int, float] = {}
    clamp: dict[int, float] = {}
    backend = "V4L2"

    def __init__(self, source):
        self.source, self.values, self.order = source, {}, []

    def isOpened(self):
        return True

    def getBackendName(self):
        return self.backend

    def set(self, prop, value):
        self.order.append(prop)
        if prop in self.refuse:
            self.values[prop] = self.refuse[prop]
            return False
        self.values[prop] = self.clamp.get(prop, value)
        return True

    def get(self, prop):
        return self.values.get(prop, 0.0)

    def read(self):
        return True, np.full((camera.RAW_SIZE[1], camera.RAW_SIZE[0], 3), 90, np.uint8)

    def release(self):
        pass


@pytest.fixture
def fake(monkeypatch):
    monkeypatch.setattr(_FakeCapture, "refuse", {})
    monkeypatch.setattr(_FakeCapture, "clamp", {})
    monkeypatch.setattr(_FakeCapture, "backend", "V4L2")
    monkeypatch.delenv("OPENCV_VIDEOIO_V4L_RANGE_NORMALIZED", raising=False)
    monkeypatch.setattr(camera.cv2, "VideoCapture", _FakeCapture)
    return _FakeCapture


def _warnings(caplog):
    return [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]


def test_a_device_gets_manual_exposure_156_and_white_balance_fixed_at_4600_k(fake, caplog):
    with caplog.at_level(logging.WARNING):
        cam = camera.Camera(0)
    v = cam.cap.values
    assert v[cv2.CAP_PROP_AUTO_EXPOSURE] == 1.0  # V4L2_EXPOSURE_MANUAL
    assert v[cv2.CAP_PROP_EXPOSURE] == 156.0  # Minsight's camera node
    assert v[cv2.CAP_PROP_AUTO_WB] == 0.0
    assert v[cv2.CAP_PROP_WB_TEMPERATURE] == 4600.0
    order = cam.cap.order  # the automatic control off before its manual value
    assert order.index(cv2.CAP_PROP_AUTO_EXPOSURE) < order.index(cv2.CAP_PROP_EXPOSURE)
    assert order.index(cv2.CAP_PROP_AUTO_WB) < order.index(cv2.CAP_PROP_WB_TEMPERATURE)
    assert cam.controls == {
        "auto_exposure": {"asked": 1.0, "read": 1.0},
        "exposure": {"asked": 156.0, "read": 156.0},
        "auto_wb": {"asked": 0.0, "read": 0.0},
        "wb_temperature": {"asked": 4600.0, "read": 4600.0},
    }
    assert _warnings(caplog) == []


def test_manual_exposure_is_0_25_where_opencv_normalises_the_range(fake, monkeypatch):
    monkeypatch.setenv("OPENCV_VIDEOIO_V4L_RANGE_NORMALIZED", "1")
    assert camera.Camera(0).cap.values[cv2.CAP_PROP_AUTO_EXPOSURE] == 0.25
    monkeypatch.delenv("OPENCV_VIDEOIO_V4L_RANGE_NORMALIZED")
    monkeypatch.setattr(fake, "backend", "DSHOW")
    assert camera.Camera(0).cap.values[cv2.CAP_PROP_AUTO_EXPOSURE] == 0.25


@pytest.mark.parametrize(
    "how, prop, name, asked, camera_value, words",
    [
        ("refuse", cv2.CAP_PROP_AUTO_WB, "auto_wb", 0.0, 1.0, "asked 0, set refused, reads 1"),
        ("clamp", cv2.CAP_PROP_EXPOSURE, "exposure", 156.0, 150.0, "asked 156, set accepted, reads 150"),
    ],
)
def test_a_refused_control_is_one_line_naming_it_and_the_camera_still_records(
    fake, monkeypatch, caplog, how, prop, name, asked, camera_value, words
):
    monkeypatch.setattr(fake, how, {prop: camera_value})
    with caplog.at_level(logging.WARNING):
        cam = camera.Camera(2)
    lines = _warnings(caplog)
    assert len(lines) == 1 and "\n" not in lines[0], lines
    assert lines[0].startswith("camera 2 (V4L2): ") and f"{name} not fixed" in lines[0] and words in lines[0], lines
    assert cam.controls[name] == {"asked": asked, "read": camera_value}
    others = {k: c for k, c in cam.controls.items() if k != name}
    assert all(c["asked"] == c["read"] for c in others.values()), others
    frame = cam.read()
    assert frame.shape == (*camera.IMAGE_SIZE, 3) and frame.dtype == np.uint8 and int(frame.max()) == 90


def test_a_file_is_not_sent_camera_controls(fake, caplog):
    with caplog.at_level(logging.WARNING):
        cam = camera.Camera("trial.avi")
    assert cam.controls == {} and cam.cap.order == [] and _warnings(caplog) == []


def test_the_reference_defaults_to_archive_reference_frames_and_reads_as_their_mean():
    assert archive.REFERENCE_FRAMES == 30
    cam = CountingCamera()
    ref = camera.take_reference(cam, "day1_lab")
    assert ref.frames.shape == (archive.REFERENCE_FRAMES, 4, 6, 3) and len(ref.taken_at) == archive.REFERENCE_FRAMES
    assert cam.count == camera.WARMUP_FRAMES + archive.REFERENCE_FRAMES
    assert f"{archive.REFERENCE_FRAMES} no-contact frames after {camera.WARMUP_FRAMES} warm-up" in ref.how
    # frames 20 .. 49 (the warm-up's 20 discarded): mean 34.5, rounded to the nearest grey level (even)
    mean = ref.mean_frame()
    assert mean.dtype == np.uint8 and mean.shape == (4, 6, 3) and int(mean[0, 0, 0]) == 34


def test_the_recorder_flag_defaults_to_archive_reference_frames():
    from acquisition import record

    assert record.FLAGS["reference_frames"].default == archive.REFERENCE_FRAMES
