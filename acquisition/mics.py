"""Laptop side of the microphone stream: re-framing, gap and latency tracking, ring buffer, windows.

TCP delivers the Pi's packets (`wire`) as an arbitrary byte stream: a `recv` may end in the middle
of a header or of a sample. `FrameAssembler` turns whatever chunks arrive into whole packets.
`MicReceiver` runs one thread that feeds a `RingBuffer` (the latest second or so, for the
per-step windows) and, while a trial records, the raw stream itself. Every audio frame has an
absolute index (frames since the Pi started streaming); a period the Pi dropped leaves a gap that
is filled with zeros, so indices stay aligned with time, and is counted.
"""

from __future__ import annotations

import socket
import threading
import time

import numpy as np

from acquisition import wire
from fabricjax.store import archive

LATE_S = 0.03  # a packet this much later than the best-case latency counts as late


class MicError(RuntimeError):
    """The microphone stream is broken: connection lost, silent, or not speaking the protocol."""


class FrameAssembler:
    """Bytes in any chunking -> whole packets (first frame index, (n, 2) int32 frames)."""

    def __init__(self):
        self.buf = bytearray()
        self.offset = 0  # stream bytes consumed, for error messages

    def feed(self, data: bytes) -> list[tuple[int, int, np.ndarray]]:
        self.buf += data
        packets = []
        while len(self.buf) >= wire.HEADER.size:
            magic, seq, first, n = wire.HEADER.unpack_from(self.buf)
            if magic != wire.MAGIC:
                raise MicError(f"microphone stream out of sync at byte {self.offset}: bad magic {bytes(magic)!r}")
            size = wire.HEADER.size + n * wire.FRAME_BYTES
            if len(self.buf) < size:
                break
            frames = (
                np.frombuffer(self.buf, "<i4", n * wire.CHANNELS, wire.HEADER.size).reshape(n, wire.CHANNELS).copy()
            )
            packets.append((seq, first, frames))
            del self.buf[:size]
            self.offset += size
        return packets


class RingBuffer:
    """Fixed-capacity (capacity, 2) int32 ring; `end` counts every frame ever written."""

    def __init__(self, capacity: int = 1 << 16):
        self.data = np.zeros((capacity, wire.CHANNELS), np.int32)
        self.end = 0

    def write(self, frames: np.ndarray) -> None:
        cap, n = len(self.data), len(frames)
        kept = frames[-cap:]
        self.data[(self.end + n - len(kept) + np.arange(len(kept))) % cap] = kept
        self.end += n

    def latest(self, n: int) -> np.ndarray:
        """The `n` newest frames as (2, n); zeros before the first frame ever written."""
        if n > len(self.data):
            raise ValueError(f"window {n} exceeds ring capacity {len(self.data)}")
        idx = np.arange(self.end - n, self.end) % len(self.data)
        out = self.data[idx].T.copy()
        out[:, : max(0, n - self.end)] = 0
        return out


class MicReceiver:
    """Connects to the Pi sender and keeps receiving on a background thread."""

    def __init__(self, host: str, port: int, *, connect_timeout: float = 5.0, silence_s: float = 0.5):
        self.address, self.silence_s = f"{host}:{port}", silence_s
        self.sock = socket.create_connection((host, port), timeout=connect_timeout)
        self.sock.settimeout(0.2)
        self.ring = RingBuffer()
        self.assembler = FrameAssembler()
        self.lock = threading.Lock()
        self.error: MicError | None = None
        self.dropped_frames = self.late_packets = self.packets = 0
        self.max_late_s = 0.0
        self._best_latency = np.inf
        self._last_arrival = time.monotonic()
        self._record: list[np.ndarray] | None = None
        self._record_start = self.origin = 0
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name="mic-receiver", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                try:
                    data = self.sock.recv(65536)
                except socket.timeout:
                    continue
                if not data:
                    raise MicError(f"Pi sender at {self.address} closed the connection after {self.ring.end} frames")
                now = time.monotonic()
                for seq, first, frames in self.assembler.feed(data):
                    self._accept(first, frames, now)
        except (MicError, OSError) as e:
            self.error = e if isinstance(e, MicError) else MicError(f"Pi sender at {self.address}: {e}")

    def _accept(self, first: int, frames: np.ndarray, now: float) -> None:
        with self.lock:
            if self.packets == 0:  # absolute indices are the Pi's: its stream may have started earlier
                self.ring.end = self.origin = first
            if first < self.ring.end:
                raise MicError(f"packet at frame {first} overlaps frames already received (up to {self.ring.end})")
            if first > self.ring.end:  # periods the Pi dropped: zeros keep indices aligned with time
                gap = np.zeros((first - self.ring.end, wire.CHANNELS), np.int32)
                self.dropped_frames += len(gap)
                self._store(gap)
            self._store(frames)
            self.packets += 1
            latency = now - self.ring.end / wire.RATE
            self._best_latency = min(self._best_latency, latency)
            late = latency - self._best_latency
            self.max_late_s = max(self.max_late_s, late)
            self.late_packets += late > LATE_S
            self._last_arrival = now

    def _store(self, frames: np.ndarray) -> None:
        self.ring.write(frames)
        if self._record is not None:
            self._record.append(frames)

    def check(self) -> None:
        """Raise the stream's failure, including silence (a stalled Pi), in the caller's thread."""
        if self.error is not None:
            raise self.error
        if time.monotonic() - self._last_arrival > self.silence_s:
            raise MicError(f"no audio from the Pi sender at {self.address} for {self.silence_s} s")

    def wait_for(self, n_frames: int, timeout: float = 5.0) -> None:
        deadline = time.monotonic() + timeout
        while self.packets == 0 or self.ring.end - self.origin < n_frames:
            self.check()
            if time.monotonic() > deadline:
                raise MicError(f"Pi sender at {self.address}: fewer than {n_frames} frames after {timeout} s")
            time.sleep(0.005)

    def latest(self, n: int = archive.WINDOW) -> tuple[np.ndarray, int]:
        """The newest `n` samples of each mic as (2, n) int32, and the window's exclusive end index."""
        self.check()
        with self.lock:
            return self.ring.latest(n), self.ring.end

    def start_recording(self) -> int:
        """Keep the raw stream from now on, starting with the window that precedes now.
        Returns the absolute index of the first kept frame."""
        with self.lock:
            n = min(archive.WINDOW, self.ring.end - self.origin)
            self._record = [self.ring.latest(n).T.copy()] if n else []
            self._record_start = self.ring.end - n
            return self._record_start

    def stop_recording(self) -> np.ndarray:
        """The raw stream kept since `start_recording`, (2, S) int32 SPH0645 words."""
        with self.lock:
            chunks, self._record = self._record or [], None
        if not chunks:
            return np.zeros((wire.CHANNELS, 0), np.int32)
        return np.ascontiguousarray(np.concatenate(chunks).T)

    def stats(self) -> dict:
        return {
            "packets": self.packets,
            "dropped_frames": self.dropped_frames,
            "late_packets": self.late_packets,
            "max_late_ms": round(1e3 * self.max_late_s, 3),
        }

    def close(self) -> None:
        self._stop.set()
        self.thread.join(timeout=1.0)
        self.sock.close()
