"""Simulated devices behind the real code paths, driven by the scene simulator's signals.

* Servos: `SimServoBus` speaks the STS protocol on a pseudo-terminal; the unmodified `scservo_sdk`
  opens the slave's path. It answers PING, READ, WRITE and SYNC_READ (one status packet per id, in
  request order) and takes SYNC_WRITE goal positions without answering, as the servos do. The k-th
  sync read returns the simulated joint state of step k.
* Camera: the simulated Minsight images are turned back into raw 1280x960 sensor frames (inverse of
  the crop, flips and resize) and written with `cv2.VideoWriter`; the real `cv2.VideoCapture` reads them.
* Microphones: `wire.serve` on 127.0.0.1 streams the simulated SPH0645 words, paced in real time
  in 512-frame periods; the laptop-side `MicReceiver` connects to it as to a Pi.

Servos and the Pi sender run in a child process so that, as on hardware, they do not compete with
the recorder for its interpreter lock. `Faults` injects the failures the recorder must survive.
"""

from __future__ import annotations

import contextlib
import dataclasses
import multiprocessing as mp
import os
import random
import select
import socket
import tempfile
import threading
import time
import tty
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np
import scservo_sdk as scs

from acquisition import camera as camera_mod
from acquisition import servos, wire
from acquisition.camera import Camera, Reference
from acquisition.mics import MicReceiver
from acquisition.recorder import Rig
from fabricjax.force_proxy import ForceProxy
from fabricjax.store import archive


@dataclasses.dataclass(frozen=True)
class Faults:
    """Failures to inject. Counts are of sync reads (servos), frames (camera) or periods (Pi)."""

    silent_servo: tuple[int, int] | None = None  # (id, sync reads answered before it goes silent)
    corrupt_servo: tuple[int, int, int] | None = None  # (id, first bad sync read, every n-th from there)
    tcp_chunks: bool = False  # split the stream into random chunks of 1..3000 bytes
    drop_connection_after: int | None = None  # Pi closes the socket after this many periods
    drop_periods_every: int | None = None  # Pi loses every n-th period (ALSA overrun)
    repeat_frames_every: int | None = None  # camera repeats its buffer every n-th frame
    camera_stops_after: int | None = None  # camera delivers this many frames, then nothing
    seed: int = 0


# ----------------------------------------------------------------------------------------------
# Servo bus on a pseudo-terminal


def _status(servo_id: int, params: bytes = b"", error: int = 0, corrupt: bool = False) -> bytes:
    body = bytes([servo_id, len(params) + 2, error]) + params
    checksum = ~sum(body) & 0xFF
    return b"\xff\xff" + body + bytes([checksum ^ 0x5A if corrupt else checksum])


class SimServoBus:
    """Six STS3215 servos on one pseudo-terminal; `path` is what `scservo_sdk.PortHandler` opens."""

    def __init__(self, joints: np.ndarray, ids=servos.DEFAULT_IDS, faults: Faults = Faults()):
        self.joints, self.ids, self.faults = joints, tuple(ids), faults
        self.memory = {i: bytearray(256) for i in self.ids}
        for i in self.ids:
            self.memory[i][servos.ADDR_MODEL : servos.ADDR_MODEL + 2] = servos.STS3215_MODEL.to_bytes(2, "little")
            self.memory[i][5] = i
        self.sync_reads = self.goal_writes = 0
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)
        self._buf = bytearray()
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name="sim-servo-bus", daemon=True)

    def start(self) -> "SimServoBus":
        self.thread.start()
        return self

    def stop(self) -> dict:
        self._stop.set()
        self.thread.join(timeout=1.0)
        os.close(self.master)
        os.close(self._slave)
        return {"sync_reads": self.sync_reads, "goal_writes": self.goal_writes}

    def _run(self) -> None:
        while not self._stop.is_set():
            if select.select([self.master], [], [], 0.05)[0]:
                self._buf += os.read(self.master, 4096)
                for packet in self._packets():
                    reply = self._handle(*packet)
                    if reply:
                        os.write(self.master, reply)

    def _packets(self) -> Iterator[tuple[int, int, bytes]]:
        buf = self._buf
        while True:
            start = buf.find(b"\xff\xff")
            if start < 0 or len(buf) < start + 4:
                return
            del buf[:start]
            end = 4 + buf[3]
            if len(buf) < end:
                return
            packet, _ = bytes(buf[:end]), buf.__delitem__(slice(0, end))
            if ~sum(packet[2:-1]) & 0xFF == packet[-1]:  # a real servo ignores a garbled packet
                yield packet[2], packet[4], packet[5:-1]

    def _silent(self, servo_id: int) -> bool:
        f = self.faults.silent_servo
        return f is not None and f[0] == servo_id and self.sync_reads > f[1]

    def _set_state(self, servo_id: int, state: np.ndarray) -> None:
        angle, velocity, current = (float(x) for x in state)
        words = {
            56: servos.encode_sign_magnitude(servos.angle_to_counts(angle), 15),
            58: servos.encode_sign_magnitude(int(round(velocity / servos.RAD_PER_COUNT)), 15),
            60: servos.encode_sign_magnitude(int(np.clip(current / 1.2 * 1000, -1000, 1000)), 10),
            69: servos.encode_sign_magnitude(int(round(current / servos.AMP_PER_COUNT)), 15),
        }
        mem = self.memory[servo_id]
        for addr, value in words.items():
            mem[addr : addr + 2] = value.to_bytes(2, "little")
        mem[62], mem[63], mem[66] = 74, 31, int(abs(velocity) > 0.01)  # 7.4 V, 31 degC, moving

    def _handle(self, servo_id: int, instruction: int, params: bytes) -> bytes:
        if instruction == scs.INST_SYNC_READ:
            address, length, ids = params[0], params[1], params[2:]
            self.sync_reads += 1
            step = min(self.sync_reads - 1, len(self.joints) - 1)
            out = b""
            for i in ids:
                if i not in self.memory or self._silent(i):
                    continue
                self._set_state(i, self.joints[step, self.ids.index(i)])
                f = self.faults.corrupt_servo
                corrupt = (
                    f is not None and f[0] == i and self.sync_reads >= f[1] and (self.sync_reads - f[1]) % f[2] == 0
                )
                out += _status(i, bytes(self.memory[i][address : address + length]), corrupt=corrupt)
            return out
        if instruction == scs.INST_SYNC_WRITE:
            address, length = params[0], params[1]
            for j in range(2, len(params), length + 1):
                if params[j] in self.memory:
                    self.memory[params[j]][address : address + length] = params[j + 1 : j + 1 + length]
            self.goal_writes += address == servos.ADDR_GOAL_POSITION
            return b""
        if servo_id not in self.memory or self._silent(servo_id):
            return b""
        if instruction == scs.INST_PING:
            return _status(servo_id)
        if instruction == scs.INST_READ:
            return _status(servo_id, bytes(self.memory[servo_id][params[0] : params[0] + params[1]]))
        if instruction == scs.INST_WRITE:
            self.memory[servo_id][params[0] : params[0] + len(params) - 1] = params[1:]
            return _status(servo_id)
        return _status(servo_id, error=0)


# ----------------------------------------------------------------------------------------------
# Camera


def raw_frame(image: np.ndarray) -> np.ndarray:
    """Inverse of `camera.preprocess`: a 308x410 RGB image as the 1280x960 BGR sensor frame."""
    width = camera_mod.CROP_COLUMNS[1] - camera_mod.CROP_COLUMNS[0]
    inner = cv2.flip(cv2.resize(image, (width, camera_mod.RAW_SIZE[1]), interpolation=cv2.INTER_LINEAR), -1)
    frame = np.zeros((camera_mod.RAW_SIZE[1], camera_mod.RAW_SIZE[0], 3), np.uint8)
    frame[:, camera_mod.CROP_COLUMNS[0] : camera_mod.CROP_COLUMNS[1]] = cv2.cvtColor(inner, cv2.COLOR_RGB2BGR)
    return frame


def write_camera_video(path: Path, images: np.ndarray, faults: Faults = Faults()) -> Path:
    """Motion-JPEG video of the sensor frames (what `cv2.VideoCapture` will serve), with faults."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), archive.STEP_RATE, camera_mod.RAW_SIZE)
    if not writer.isOpened():
        raise RuntimeError(f"cannot write the simulated camera video {path}")
    n = len(images) if faults.camera_stops_after is None else min(len(images), faults.camera_stops_after)
    frame = None
    for k in range(n):
        every = faults.repeat_frames_every
        if frame is None or not (every and k % every == every - 1):
            frame = raw_frame(images[k])
        writer.write(frame)
    writer.release()
    return path


def delivered_frames(path: Path, images: np.ndarray) -> np.ndarray:
    """`images` as the camera serves them: through the Motion-JPEG video and Minsight's
    preprocessing (what the recorder's force proxy sees, so it is calibrated on that)."""
    camera = Camera(str(write_camera_video(path, images)))
    try:
        return np.stack([camera.read() for _ in images])
    finally:
        camera.close()


# ----------------------------------------------------------------------------------------------
# Pi sender


def paced_periods(audio: np.ndarray, faults: Faults = Faults()) -> Iterator[bytes | None]:
    """(2, S) SPH0645 words as real-time ALSA periods (None for a period lost to an overrun)."""
    frames = np.ascontiguousarray(audio.T.astype("<i4"))
    t0 = time.monotonic()
    for k, start in enumerate(range(0, len(frames) - wire.PERIOD + 1, wire.PERIOD)):
        due = t0 + (start + wire.PERIOD) / wire.RATE
        delay = due - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        if faults.drop_connection_after is not None and k >= faults.drop_connection_after:
            return
        every = faults.drop_periods_every
        yield None if every and k % every == every - 1 else frames[start : start + wire.PERIOD].tobytes()


def chunked_sender(seed: int):
    """A `send` for `wire.serve` that cuts the byte stream at random places (mid-header, mid-sample)."""
    rng = random.Random(seed)

    def send(conn: socket.socket, packet: bytes) -> None:
        i = 0
        while i < len(packet):
            n = rng.randint(1, 3000)
            conn.sendall(packet[i : i + n])
            i += n

    return send


# ----------------------------------------------------------------------------------------------
# The devices process and the simulated hand


def _devices_main(pipe, signals_path: str, faults: Faults) -> None:
    """Child process: servo bus on a pty and the Pi sender on 127.0.0.1, until told to stop."""
    with np.load(signals_path) as signals:
        joints, audio = signals["joints"], signals["audio"]
    # A Pi keeps streaming after the trial: a recorder that fell behind must not run out of audio
    # (steps are served per read, audio per wall-clock second). Repeat the last second for 5 s.
    audio = np.concatenate([audio, np.tile(audio[:, -wire.RATE :], 5)], axis=1)
    bus = SimServoBus(joints, faults=faults).start()
    listener = socket.create_server(("127.0.0.1", 0))
    result: dict = {}
    send = chunked_sender(faults.seed) if faults.tcp_chunks else wire.send_all
    sender = threading.Thread(
        target=lambda: result.update(wire.serve(paced_periods(audio, faults), listener=listener, send=send)),
        daemon=True,
    )
    sender.start()
    pipe.send((bus.path, listener.getsockname()[1]))
    pipe.recv()  # stop
    stats = bus.stop()
    sender.join(timeout=0.5)
    pipe.send({"servos": stats, "pi": result})


@dataclasses.dataclass
class SimulatedSignals:
    """What the simulated devices serve: one simulated trial's streams, per 50 Hz step."""

    joints: np.ndarray  # (T, 6, 3) float32
    images: np.ndarray  # (T, 308, 410, 3) uint8
    force: np.ndarray  # (T,) float32, N
    audio: np.ndarray  # (2, S) int32 SPH0645 words
    reference: np.ndarray  # no-contact Minsight image
    source: dict


@contextlib.contextmanager
def simulated_rig(signals: SimulatedSignals, faults: Faults = Faults(), *, servo_retries: int = 2) -> Iterator[Rig]:
    """Start the simulated devices, open them through the real drivers, yield the `Rig`.

    On exit, `rig.source['device_stats']` holds what the devices saw (sync reads, goal writes, packets)."""
    with tempfile.TemporaryDirectory(prefix="fabricjax-simdev-") as tmp:
        tmp = Path(tmp)
        np.savez(tmp / "signals.npz", joints=signals.joints, audio=signals.audio)
        video = write_camera_video(tmp / "minsight.avi", signals.images, faults)
        ctx = mp.get_context("spawn")
        parent, child = ctx.Pipe()
        proc = ctx.Process(target=_devices_main, args=(child, str(tmp / "signals.npz"), faults), daemon=True)
        proc.start()
        rig = None
        try:
            if not parent.poll(30):
                raise RuntimeError("simulated devices did not start within 30 s")
            pty_path, port = parent.recv()
            closing = slice(0, int(np.argmax(signals.force >= 0.1)) + 1)  # no contact .. grasp: no shear yet
            reference = delivered_frames(tmp / "reference.avi", signals.reference[None])[0]
            delivered = delivered_frames(tmp / "closing.avi", signals.images[closing])
            force = ForceProxy.calibrate(reference, delivered, signals.force[closing])
            bus = servos.ServoBus(pty_path, retries=servo_retries)
            bus.ping_all()
            bus.set_torque(True)
            source = {
                "kind": "simulated-devices",
                "servo_port": pty_path,
                "camera": str(video),
                "pi": f"127.0.0.1:{port}",
                "faults": dataclasses.asdict(faults),
                **signals.source,
            }
            scene = signals.source.get("scene", {})
            session = Reference(
                reference[None],
                f"day{scene.get('day', 1)}_{scene.get('condition', 'lab')}",
                "simulated devices: the session's no-contact frame after the camera's warm-up, through the "
                "camera's codec",
                None,
            )
            rig = Rig(
                bus=bus,
                camera=Camera(str(video)),
                mics=MicReceiver("127.0.0.1", port),
                force=force,
                source=source,
                reference=session,
            )
            yield rig
        finally:
            if rig is not None:
                rig.close()
            if proc.is_alive():
                parent.send("stop")
                if parent.poll(3):
                    stats = parent.recv()
                    if rig is not None:
                        rig.source["device_stats"] = stats
            proc.join(timeout=3)
            if proc.is_alive():
                proc.terminate()
