"""A WAV + CSV + video trial folder becomes an archive aligned as the recorder aligns."""

import subprocess
import sys

import cv2
import numpy as np
import pytest
from scipy.io import wavfile

from acquisition import hand_folder, ros_bag
from acquisition.recording import RecordingImportError
from fabricjax import archive
from fabricjax.errors import UserError

N, H, W, FPS = 15, 8, 10, 50
TRIAL = {"fabric_id": 4, "day": 1, "trial": 2, "condition": "lab"}
T_CAM = 0.10001  # s: first frame, after 0.1 s of audio (a full window), between two samples


def write_folder(folder, *, video=False, rate=48000, drop_column=None, seed=0):
    """Camera frames at 50 Hz from T_CAM (frames.csv), joints at 100 Hz from 0, WAVs from 0."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True)
    # one flat colour per frame: MJPG keeps it within a few grey levels (it would smear noise)
    frames = np.broadcast_to(rng.integers(0, 255, size=(N, 1, 1, 3), dtype=np.uint8), (N, H, W, 3)).copy()
    if video:
        out = cv2.VideoWriter(str(folder / "camera.avi"), cv2.VideoWriter_fourcc(*"MJPG"), FPS, (W, H))
        for f in frames:
            out.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
        out.release()
    else:
        (folder / "camera").mkdir()
        for i, f in enumerate(frames):
            cv2.imwrite(str(folder / "camera" / f"{i:04d}.png"), cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    frame_t = T_CAM + np.arange(N) / FPS
    np.savetxt(folder / "frames.csv", frame_t, header="time", comments="", fmt="%.6f")
    n_audio = int(rate * (frame_t[-1] + 0.05))
    internal = rng.integers(-(2**15), 2**15, size=n_audio, dtype=np.int16)
    external = (rng.integers(-(2**17), 2**17, size=n_audio) << 14).astype(np.int32)
    wavfile.write(folder / "internal.wav", rate, internal)
    wavfile.write(folder / "external.wav", rate, external)
    joint_t = np.arange(2 * N + 15) * 0.01
    joints = rng.normal(size=(len(joint_t), 6, 3))
    cols = ["time", *(f"{j}_{f}" for j in archive.JOINT_NAMES for f in archive.JOINT_FIELDS)]
    table = np.column_stack([joint_t, joints.reshape(len(joint_t), -1)])
    if drop_column is not None:
        keep = [i for i, c in enumerate(cols) if c != drop_column]
        cols, table = [cols[i] for i in keep], table[:, keep]
    np.savetxt(folder / "joints.csv", table, delimiter=",", header=",".join(cols), comments="", fmt="%.9g")
    return dict(frames=frames, frame_t=frame_t, internal=internal, external=external, joint_t=joint_t, joints=joints)


@pytest.mark.parametrize("video", [False, True])
def test_folder_becomes_aligned_archive(tmp_path, video):
    rec = write_folder(tmp_path / "trial", video=video)
    a = hand_folder.import_folder(tmp_path / "trial", TRIAL)
    a = archive.read_archive(archive.write_archive(tmp_path / "out" / archive.trial_filename(a.meta), a))
    assert a.n_steps == N
    np.testing.assert_allclose(a.timestamps, np.arange(N) / FPS, atol=1e-6)
    # frame i at T_CAM + i/50 holds samples 0 .. floor(48000 t)
    want = np.floor(rec["frame_t"] * 48000).astype(np.int64) + 1
    np.testing.assert_array_equal(a.window_end, np.stack([want, want], axis=1))
    np.testing.assert_array_equal(a.audio[0], rec["internal"].astype(np.int32) << 16)
    np.testing.assert_array_equal(a.audio[1], rec["external"])
    latest = np.searchsorted(rec["joint_t"], rec["frame_t"], side="right") - 1
    np.testing.assert_allclose(a.joints, rec["joints"][latest].astype(np.float32), rtol=1e-6)
    if video:  # MJPG is lossy: the frames come back close, not equal
        assert np.abs(a.images.astype(int) - rec["frames"]).mean() < 8
    else:
        np.testing.assert_array_equal(a.images, rec["frames"])


def test_folder_errors_name_file_field_and_problem(tmp_path):
    write_folder(tmp_path / "rate", rate=44100)
    with pytest.raises(RecordingImportError, match=r"rate/internal\.wav: rate: sample rate 44100 Hz"):
        hand_folder.import_folder(tmp_path / "rate", TRIAL)
    assert hand_folder.import_folder(tmp_path / "rate", TRIAL, resample=True).meta["import"]["resampled"]
    write_folder(tmp_path / "col", drop_column="palm_current")
    with pytest.raises(RecordingImportError, match=r"joints\.csv: palm_current: column missing"):
        hand_folder.import_folder(tmp_path / "col", TRIAL)
    (tmp_path / "rate" / "external.wav").unlink()
    done = subprocess.run([sys.executable, "-m", "acquisition.import_folder", str(tmp_path / "rate"), f"--out={tmp_path / 'o'}",
                           "--fabric=4", "--day=1", "--trial=0"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
    assert "external.wav: <file>: no such file" in done.stderr


def test_bag_import_without_rosbags_says_how_to_install(tmp_path, monkeypatch):
    for name in {"rosbags", *(m for m in sys.modules if m.startswith("rosbags."))}:
        monkeypatch.setitem(sys.modules, name, None)  # as if the optional package were absent
    with pytest.raises(UserError, match=r'pip install -e "\.\[bags\]"'):
        ros_bag.import_bag(tmp_path, {}, TRIAL)
