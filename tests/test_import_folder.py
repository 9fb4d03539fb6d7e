"""A WAV + CSV + video trial folder becomes an archive aligned as the recorder aligns."""

import subprocess
import sys

import cv2
import numpy as np
import pytest
from scipy.io import wavfile

from fabricjax.errors import UserError
from fabricjax.importers import hand_folder, ros_bag
from fabricjax.importers.alignment import ReferenceSource
from fabricjax.importers.streams import RecordingImportError
from fabricjax.store import archive

N, H, W, FPS = 15, 8, 10, 50
TRIAL = {"fabric_id": 4, "day": 1, "trial": 2, "condition": "lab"}
T_CAM = 0.10001  # s: first frame, after 0.1 s of audio (a full window), between two samples
REFERENCE = ReferenceSource("reference.png")  # as --reference=reference.png names it


def write_folder(folder, *, video=False, rate=48000, drop_column=None, seed=0):
    """Camera frames at 50 Hz from T_CAM (frames.csv), joints at 100 Hz from 0, WAVs from 0, and the
    session's no-contact frame as reference.png."""
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
    reference = rng.integers(0, 255, size=(H, W, 3), dtype=np.uint8)
    cv2.imwrite(str(folder / "reference.png"), cv2.cvtColor(reference, cv2.COLOR_RGB2BGR))
    return dict(
        frames=frames,
        frame_t=frame_t,
        internal=internal,
        external=external,
        joint_t=joint_t,
        joints=joints,
        reference=reference,
    )


@pytest.mark.parametrize("video", [False, True])
def test_folder_becomes_aligned_archive(tmp_path, video):
    rec = write_folder(tmp_path / "trial", video=video)
    a = hand_folder.import_folder(tmp_path / "trial", TRIAL, reference=REFERENCE)
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
    np.testing.assert_array_equal(a.reference, rec["reference"][None])  # a PNG: exact
    assert a.meta["reference"] == {
        "how": "imported: 1 frame of the file reference.png (relative to the trial folder)",
        "session": "day1_lab",
        "times_s": None,
    }
    assert a.meta["source"]["reference"] == "reference.png"


def test_a_reference_file_npy_or_pre_contact_frames_and_none_is_a_one_line_error(tmp_path):
    rec = write_folder(tmp_path / "t")
    np.save(tmp_path / "t" / "ref.npy", np.stack([rec["reference"]] * 2))
    a = hand_folder.import_folder(tmp_path / "t", {**TRIAL, "session": "monday"}, reference=ReferenceSource("ref.npy"))
    np.testing.assert_array_equal(a.reference, np.stack([rec["reference"]] * 2))
    assert a.meta["reference"]["session"] == "monday" and a.meta["reference"]["how"].startswith(
        "imported: 2 frames of the file ref.npy"
    )
    b = hand_folder.import_folder(tmp_path / "t", TRIAL, reference=ReferenceSource(None, 3, "the command line"))
    np.testing.assert_array_equal(b.reference, rec["frames"][:3])
    assert b.meta["reference"] == {
        "how": "imported: the trial's first 3 frames (pre-contact, as the command line asks)",
        "session": "day1_lab",
        "times_s": pytest.approx([0.0, 0.02, 0.04]),
    }
    np.save(tmp_path / "t" / "small.npy", rec["reference"][:4])
    with pytest.raises(RecordingImportError, match=r"small\.npy: frames: 4x10 pixels, the camera's frames are 8x10"):
        hand_folder.import_folder(tmp_path / "t", TRIAL, reference=ReferenceSource("small.npy"))
    with pytest.raises(
        RecordingImportError,
        match=r"t: <folder>: not a trial folder of the hand's layout: missing gone\.png \(the reference "
        r"--reference names\)",
    ):
        hand_folder.import_folder(tmp_path / "t", TRIAL, reference=ReferenceSource("gone.png"))
    cmd = [
        sys.executable,
        "-m",
        "experiments.import_folder",
        str(tmp_path / "t"),
        f"--out={tmp_path / 'o'}",
        "--fabric=4",
        "--day=1",
        "--trial=0",
    ]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and not (tmp_path / "o").exists()
    assert done.stderr.strip().splitlines() == [
        f"error: {tmp_path / 't'}: --reference: missing: a camera needs its session's no-contact reference: "
        "name the file of the trial folder that holds it (pass --reference=reference.png), or pass "
        "--reference=pre_contact to use the trial's first frames"
    ]
    done = subprocess.run(
        cmd + ["--reference=pre_contact", "--reference_frames=2"], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    np.testing.assert_array_equal(
        archive.read_archive(tmp_path / "o" / "fabric04_day1_trial00_lab.npz").reference, rec["frames"][:2]
    )


def test_folder_errors_name_file_field_and_problem(tmp_path):
    write_folder(tmp_path / "rate", rate=44100)
    with pytest.raises(RecordingImportError, match=r"rate/internal\.wav: rate: sample rate 44100 Hz"):
        hand_folder.import_folder(tmp_path / "rate", TRIAL, reference=REFERENCE)
    assert hand_folder.import_folder(tmp_path / "rate", TRIAL, reference=REFERENCE, resample=True).meta["import"][
        "resampled"
    ]
    write_folder(tmp_path / "col", drop_column="palm_current")
    with pytest.raises(RecordingImportError, match=r"joints\.csv: palm_current: column missing"):
        hand_folder.import_folder(tmp_path / "col", TRIAL, reference=REFERENCE)
    (tmp_path / "rate" / "external.wav").unlink()
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "experiments.import_folder",
            str(tmp_path / "rate"),
            f"--out={tmp_path / 'o'}",
            "--fabric=4",
            "--day=1",
            "--trial=0",
            "--reference=reference.png",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
    assert "rate: <folder>: not a trial folder of the hand's layout: missing external.wav;" in done.stderr


def test_another_rigs_folder_names_every_missing_file_and_the_rig_import(tmp_path):
    from fabricjax.importers import example_rig

    example_rig.write_recordings(tmp_path / "rig", ["felt"], 1, seconds=(2.0, 2.0))
    folder = tmp_path / "rig" / "recordings" / "00_000"
    with pytest.raises(RecordingImportError) as e:
        hand_folder.import_folder(folder, TRIAL, reference=REFERENCE)
    assert str(e.value).startswith(
        f"{folder}: <folder>: not a trial folder of the hand's layout: missing internal.wav, external.wav, camera{{"
    )
    assert "joints.csv" not in str(e.value).split(";")[0]  # the folder has one
    assert "python -m experiments.import_manifest MANIFEST.csv --out=DIR --rig=rig.toml" in str(e.value)


def test_a_cut_off_wav_imports_as_incomplete(tmp_path):
    write_folder(tmp_path / "t")
    wav = tmp_path / "t" / "external.wav"
    wav.write_bytes(wav.read_bytes()[: wav.stat().st_size * 3 // 4])
    a = hand_folder.import_folder(tmp_path / "t", TRIAL, reference=REFERENCE)
    assert a.meta["complete"] is False and a.meta["import"]["truncated"] == ["external.wav"]
    write_folder(tmp_path / "whole")
    assert hand_folder.import_folder(tmp_path / "whole", TRIAL, reference=REFERENCE).meta["complete"] is True


def test_joint_timestamps_in_milliseconds_header_only_and_holes(tmp_path):
    write_folder(tmp_path / "ms")
    table = np.loadtxt(tmp_path / "ms" / "joints.csv", delimiter=",", skiprows=1)
    header = (tmp_path / "ms" / "joints.csv").read_text().splitlines()[0]
    table[:, 0] *= 1000
    np.savetxt(tmp_path / "ms" / "joints.csv", table, delimiter=",", header=header, comments="", fmt="%.9g")
    with pytest.raises(
        RecordingImportError,
        match=r"ms/joints\.csv: time: timestamps span 440, but the microphones hold 0\.43 s .* must be seconds",
    ):
        hand_folder.import_folder(tmp_path / "ms", TRIAL, reference=REFERENCE)
    (tmp_path / "ms" / "joints.csv").write_text(header + "\n")
    with pytest.raises(RecordingImportError, match=r"joints\.csv: <rows>: no readings \(a header row only\)"):
        hand_folder.import_folder(tmp_path / "ms", TRIAL, reference=REFERENCE)
    write_folder(tmp_path / "hole")
    table = np.loadtxt(tmp_path / "hole" / "joints.csv", delimiter=",", skiprows=1)
    held = (table[:, 0] > 0.15) & (table[:, 0] < 0.30)  # 150 ms without a reading: steps hold the last one
    np.savetxt(tmp_path / "hole" / "joints.csv", table[~held], delimiter=",", header=header, comments="", fmt="%.9g")
    gaps = hand_folder.import_folder(tmp_path / "hole", TRIAL, reference=REFERENCE).meta["import"]["joint_gaps"]
    assert (
        len(gaps) == 1
        and gaps[0]["from_s"] == pytest.approx(0.15)
        and gaps[0]["seconds"] == pytest.approx(0.15, abs=0.011)
        and gaps[0]["steps"] == 7
    )


def test_a_wav_shorter_than_one_window_is_named(tmp_path):
    """internal.wav cut to 1,000 samples gives no frame a full window: the error names the WAV, in
    one line, not the camera whose frames it leaves without audio."""
    write_folder(tmp_path / "t")
    wav = tmp_path / "t" / "internal.wav"
    rate, samples = wavfile.read(wav)
    wavfile.write(wav, rate, samples[:1000])
    with pytest.raises(RecordingImportError) as e:
        hand_folder.import_folder(tmp_path / "t", TRIAL, reference=REFERENCE)
    assert str(e.value) == (
        f"{wav}: samples: 1000 samples (0.021 s at 48000 Hz), shorter than one step's window (2048 samples at "
        "48000 Hz, 0.043 s): the recording is cut short"
    )


def test_bag_import_without_rosbags_says_how_to_install(tmp_path, monkeypatch):
    for name in {"rosbags", *(m for m in sys.modules if m.startswith("rosbags."))}:
        monkeypatch.setitem(sys.modules, name, None)  # as if the optional package were absent
    with pytest.raises(UserError, match=r'pip install -e "\.\[bags\]"'):
        ros_bag.import_bag(tmp_path, {}, TRIAL)
