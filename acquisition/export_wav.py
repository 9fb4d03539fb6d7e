"""Listen to a trial: `python -m acquisition.export_wav ARCHIVE [ARCHIVE ...] --out=DIR`.

Writes each microphone's stream as a 48 kHz 32-bit WAV (the archive's int32 words, unchanged) and
the meta as a JSON sidecar (`acquisition.exporting`)."""

from __future__ import annotations

from absl import flags

from acquisition import exporting
from fabricjax import cli
from fabricjax.errors import UserError

FLAGS = flags.FLAGS
flags.DEFINE_string("out", ".", "Folder to write the WAV files and JSON sidecars into.")


def main(argv):
    if len(argv) < 2:
        raise UserError("give at least one archive: python -m acquisition.export_wav ARCHIVE --out=DIR")
    for path in argv[1:]:
        for written in exporting.export_wav(path, FLAGS.out):
            print(written)


if __name__ == "__main__":
    cli.run(main)
