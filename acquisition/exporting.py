"""Trial archives out to files any audio tool opens: one 48 kHz WAV per microphone, the raw int32
SPH0645 words unchanged (the 18 valid bits sit in bits 31..14, so a 32-bit PCM player hears them at
full scale), and the meta as a JSON sidecar. Reading the WAV back gives the archive's samples bit
for bit."""

from __future__ import annotations

import io
import json
from pathlib import Path

from scipy.io import wavfile

from fabricjax.store import archive
from fabricjax.store.atomic import atomic_open


def export_wav(path: str | Path, out_dir: str | Path) -> list[Path]:
    """Write `<stem>_<mic>.wav` per microphone and `<stem>.json` into `out_dir`; returns the paths."""
    path = Path(path)
    trial = archive.read_archive(path, images=False)
    out_dir = Path(out_dir)
    written = []
    for row, mic in enumerate(archive.MIC_NAMES):
        buf = io.BytesIO()
        wavfile.write(buf, archive.AUDIO_RATE, trial.audio[row])
        target = out_dir / f"{path.stem}_{mic}.wav"
        with atomic_open(target) as f:
            f.write(buf.getvalue())
        written.append(target)
    sidecar = out_dir / f"{path.stem}.json"
    with atomic_open(sidecar, "w") as f:
        f.write(json.dumps(trial.meta | {"exported_from": str(path), "wav_files": [p.name for p in written]}, indent=1))
    return [*written, sidecar]
