"""export_wav: every microphone's samples come back from the WAV bit for bit, with the meta beside them."""

import json
import subprocess
import sys

import numpy as np
from scipy.io import wavfile

from acquisition import exporting
from fabricjax.store import archive
from tests.helpers import tiny_archive


def test_wav_round_trips_samples_bit_exactly(tmp_path):
    a = tiny_archive(n_steps=10, images=None)
    path = archive.write_archive(tmp_path / "data" / archive.trial_filename(a.meta), a)
    written = exporting.export_wav(path, tmp_path / "wav")
    assert [p.name for p in written] == [f"{path.stem}_internal.wav", f"{path.stem}_external.wav", f"{path.stem}.json"]
    for row, wav in enumerate(written[:2]):
        rate, samples = wavfile.read(wav)
        assert rate == archive.AUDIO_RATE and samples.dtype == np.int32
        np.testing.assert_array_equal(samples, a.audio[row])
    meta = json.loads(written[2].read_text())
    assert meta["fabric_id"] == a.meta["fabric_id"] and meta["exported_from"] == str(path)
    assert sorted(p.name for p in (tmp_path / "data").iterdir()) == [path.name]  # nothing written beside the archive


def test_command_reports_a_damaged_archive_in_one_line(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    done = subprocess.run(
        [sys.executable, "-m", "acquisition.export_wav", str(bad), f"--out={tmp_path}"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert len(done.stderr.strip().splitlines()) == 1 and str(bad) in done.stderr
