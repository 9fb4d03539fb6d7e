"""The microphone stream from the Raspberry Pi to the laptop: wire format and the Pi-side server.

The I2S card offers only S32_LE, so `arecord -f S32_LE -c 2 -r 48000 -t raw` delivers interleaved
stereo int32 words (left = Minsound inside the thumb, right = palm), one ALSA period of 512 frames
every 10.67 ms. Each period goes out as one packet: a 20-byte header (magic b"SPH0", sequence
number, index of its first frame, frame count; little-endian) and the raw words. The header lets
the receiver re-frame the byte stream whatever TCP does to it and detect periods the Pi had to
drop. The sender never blocks the ALSA reader: when the laptop does not keep up (socket buffer
full), the period is dropped and the sequence number still advances.

Stdlib only, so it runs on a bare Pi (`python -m acquisition.pi_sender`).
"""

from __future__ import annotations

import contextlib
import select
import socket
import struct
import subprocess
from typing import Callable, Iterable, Iterator

RATE = 48000  # fabricjax.store.archive.AUDIO_RATE, repeated because this module is stdlib-only (tested equal)
CHANNELS = 2
PERIOD = 512
HEADER = struct.Struct("<4sIQI")  # magic, sequence, first frame, frames
MAGIC = b"SPH0"
FRAME_BYTES = 4 * CHANNELS
ARECORD_EXIT_S = 2.0  # how long arecord gets to exit once terminated before it is killed


@contextlib.contextmanager
def arecord_periods(device: str, period: int = PERIOD) -> Iterator[Iterator[bytes]]:
    """A context giving raw S32_LE stereo periods read from ALSA, paced by the sound card itself.

    A context, not a generator, so that arecord ends when the caller stops reading (the receiver
    went away, an error), on every path, rather than whenever the garbage collector gets to it."""
    cmd = [
        "arecord",
        "-D",
        device,
        "-c",
        str(CHANNELS),
        "-r",
        str(RATE),
        "-f",
        "S32_LE",
        "-t",
        "raw",
        f"--period-size={period}",
        "-q",
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE)

    def periods() -> Iterator[bytes]:
        size = period * FRAME_BYTES
        while True:
            block = proc.stdout.read(size)
            if len(block) < size:
                raise RuntimeError(
                    f"arecord ended (exit code {proc.poll()}); check the I2S overlay and device {device}"
                )
            yield block

    try:
        yield periods()
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=ARECORD_EXIT_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        proc.stdout.close()


def send_all(conn: socket.socket, packet: bytes) -> None:
    conn.sendall(packet)


def serve(
    periods: Iterable[bytes | None],
    host: str = "0.0.0.0",
    port: int = 5005,
    *,
    listener: socket.socket | None = None,
    send: Callable[[socket.socket, bytes], None] = send_all,
) -> dict:
    """Accept one receiver and stream `periods` to it until they end or the connection drops.

    A `None` period is one the source lost (an ALSA overrun): its frames are skipped, not sent.
    Returns counts of sent and dropped packets, and how the stream ended: "source ended", or the
    connection's error when the receiver went away (a normal end on the Pi side, which the
    caller reports if it wants: a simulated rig closes it after every trial)."""
    if listener is None:
        listener = socket.create_server((host, port))
    conn, _ = listener.accept()
    conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    seq = frame = sent = dropped = 0
    ended = "source ended"
    try:
        for block in periods:
            n = PERIOD if block is None else len(block) // FRAME_BYTES
            if block is not None and select.select([], [conn], [], 0)[1]:
                send(conn, HEADER.pack(MAGIC, seq, frame, n) + block)
                sent += 1
            else:
                dropped += 1
            seq, frame = seq + 1, frame + n
    except OSError as e:  # the laptop went away: a normal end on the Pi side
        ended = f"connection ended: {e}"
    finally:
        conn.close()
        listener.close()
    return {"sent": sent, "dropped": dropped, "frames": frame, "ended": ended}
