"""The hand's six Feetech STS servos through the unmodified `scservo_sdk`.

One broadcast SYNC_READ per control step fetches registers 56..70 (15 bytes) of all six servos:

====  =====  =================================================================
addr  bytes  register (STS3215 memory table)
====  =====  =================================================================
56    2      present position, counts, sign-magnitude (sign bit 15)
58    2      present velocity, counts/s, sign-magnitude (sign bit 15)
60    2      present load, 0.1 % of max torque, sign-magnitude (sign bit 10)
62    1      present voltage, 0.1 V
63    1      present temperature, deg C
64-68        async-write flag, status, moving flag, two reserved bytes
69    2      present current, counts, sign-magnitude (sign bit 15)
====  =====  =================================================================

Conversions to the archive's units (`archive.UNITS`):

* angle   = (position - 2048) * 2 pi / 4096 rad: 4096 counts per turn, 0 rad at mid-range (2048).
* velocity = velocity * 2 pi / 4096 rad/s (the register counts position steps per second).
* current = current * 6.5 mA. Assumption: Feetech documents the STS3215 current register in units
  of 6.5 mA; the sign bit (15) is honoured in case a firmware reports signed current.

Goal positions are sent with one GroupSyncWrite to register 42 (2 bytes) per step.
"""

from __future__ import annotations

import math
import select
import time

import numpy as np
import scservo_sdk as scs

from fabricjax.store import archive

ADDR_MODEL, ADDR_TORQUE_ENABLE, ADDR_GOAL_POSITION, ADDR_STATE = 3, 40, 42, 56
STATE_BYTES = 15  # 56..70: position .. current
STS3215_MODEL = 777
COUNTS_PER_TURN = 4096
CENTER = 2048
RAD_PER_COUNT = 2 * math.pi / COUNTS_PER_TURN
AMP_PER_COUNT = 0.0065
DEFAULT_IDS = (1, 2, 3, 4, 5, 6)  # thumb 3, middle finger 2, palm 1, in `archive.JOINT_NAMES` order
REGISTER_NAMES = {
    ADDR_MODEL: "model number (3..4)",
    ADDR_TORQUE_ENABLE: "torque enable (40)",
    ADDR_GOAL_POSITION: "goal position (42..43)",
    ADDR_STATE: "present position..current (56..70)",
}


class ServoError(RuntimeError):
    """A servo did not answer correctly after the bounded retries; names the servo and register."""

    def __init__(self, servo_id: int, joint: str, register: int, problem: str):
        self.servo_id, self.joint, self.register = servo_id, joint, register
        super().__init__(f"servo {servo_id} ({joint}), register {REGISTER_NAMES.get(register, register)}: {problem}")


def sign_magnitude(value: int, sign_bit: int) -> int:
    """Feetech encodes negative numbers as magnitude with one sign bit, not two's complement."""
    magnitude = value & ((1 << sign_bit) - 1)
    return -magnitude if value & (1 << sign_bit) else magnitude


def encode_sign_magnitude(value: int, sign_bit: int) -> int:
    return (-value) | (1 << sign_bit) if value < 0 else value


def angle_to_counts(angle_rad: float) -> int:
    return int(np.clip(round(angle_rad / RAD_PER_COUNT) + CENTER, 0, COUNTS_PER_TURN - 1))


def decode_state(data: list[int]) -> tuple[float, float, float]:
    """15 bytes from register 56 -> (angle rad, velocity rad/s, current A)."""
    word = lambda i: data[i - ADDR_STATE] | (data[i - ADDR_STATE + 1] << 8)  # noqa: E731
    angle = (sign_magnitude(word(56), 15) - CENTER) * RAD_PER_COUNT
    velocity = sign_magnitude(word(58), 15) * RAD_PER_COUNT
    current = sign_magnitude(word(69), 15) * AMP_PER_COUNT
    return angle, velocity, current


class PortHandler(scs.PortHandler):
    """The SDK's port, except that waiting for a reply sleeps in `select` instead of spinning: the
    SDK polls a non-blocking port in a busy loop, which on a small laptop starves the camera and
    the servo replies themselves of CPU."""

    def readPort(self, length):
        if not self.ser.in_waiting:
            select.select([self.ser.fileno()], [], [], 0.0005)
        return self.ser.read(length)


class ServoBus:
    """Six joints on one half-duplex bus. Not thread-safe (neither is the SDK): one loop owns it."""

    def __init__(self, port: str, ids=DEFAULT_IDS, *, baudrate: int = 1_000_000, retries: int = 2):
        if len(ids) != archive.N_JOINTS:
            raise ValueError(f"need {archive.N_JOINTS} servo ids ({', '.join(archive.JOINT_NAMES)}), got {ids}")
        self.ids, self.retries, self.retried = tuple(ids), retries, 0
        self.port = PortHandler(port)
        self.packet = scs.PacketHandler(0)  # 0: little-endian words (STS/SMS series)
        if not self.port.openPort():
            raise ServoError(0, "bus", ADDR_MODEL, f"cannot open {port} at {baudrate} baud")
        if not self.port.setBaudRate(baudrate):
            raise ServoError(0, "bus", ADDR_MODEL, f"baud rate {baudrate} not supported by the SDK")
        self.reader = scs.GroupSyncRead(self.port, self.packet, ADDR_STATE, STATE_BYTES)
        self.writer = scs.GroupSyncWrite(self.port, self.packet, ADDR_GOAL_POSITION, 2)
        for i in self.ids:
            self.reader.addParam(i)
            self.writer.addParam(i, [0, 0])

    def _joint(self, servo_id: int) -> str:
        return archive.JOINT_NAMES[self.ids.index(servo_id)] if servo_id in self.ids else "bus"

    def _fail(self, servo_id: int, register: int, result: int, error: int = 0) -> ServoError:
        problem = (
            self.packet.getTxRxResult(result) if result != scs.COMM_SUCCESS else self.packet.getRxPacketError(error)
        )
        return ServoError(
            servo_id, self._joint(servo_id), register, f"{problem.split('] ')[-1]} (after {self.retries + 1} tries)"
        )

    def _recover(self) -> None:
        """Let a late or garbled reply finish, then drop it so the retry starts on a clean line."""
        self.retried += 1
        time.sleep(0.001)
        self.port.ser.reset_input_buffer()

    def ping_all(self) -> dict[int, int]:
        """Model number of every servo; a missing or foreign servo is a clear error."""
        models = {}
        for i in self.ids:
            for attempt in range(self.retries + 1):
                model, result, error = self.packet.ping(self.port, i)
                if result == scs.COMM_SUCCESS:
                    break
                self._recover()
            else:
                raise self._fail(i, ADDR_MODEL, result, error)
            if model != STS3215_MODEL:
                raise ServoError(i, self._joint(i), ADDR_MODEL, f"model {model}, expected STS3215 ({STS3215_MODEL})")
            models[i] = model
        return models

    def set_torque(self, on: bool) -> None:
        for i in self.ids:
            for attempt in range(self.retries + 1):
                result, error = self.packet.write1ByteTxRx(self.port, i, ADDR_TORQUE_ENABLE, int(on))
                if result == scs.COMM_SUCCESS:
                    break
                self._recover()
            else:
                raise self._fail(i, ADDR_TORQUE_ENABLE, result, error)

    def read_state(self) -> np.ndarray:
        """(6, 3) float32: angle rad, velocity rad/s, current A, from one sync read (retried)."""
        for attempt in range(self.retries + 1):
            for i in self.ids:  # the SDK keeps the previous step's bytes on failure: never reuse them
                self.reader.data_dict[i] = []
            result = self.reader.txRxPacket()
            if result == scs.COMM_SUCCESS:
                return np.array([decode_state(self.reader.data_dict[i]) for i in self.ids], np.float32)
            self._recover()
        culprit = next(i for i in self.ids if len(self.reader.data_dict[i]) < STATE_BYTES)
        raise self._fail(culprit, ADDR_STATE, result)

    def write_goals(self, angles_rad) -> None:
        """Goal angle of each joint (rad) in one broadcast packet; servos do not answer it."""
        for i, a in zip(self.ids, angles_rad):
            c = angle_to_counts(float(a))
            self.writer.changeParam(i, [c & 0xFF, c >> 8])
        result = self.writer.txPacket()
        if result != scs.COMM_SUCCESS:
            raise self._fail(scs.BROADCAST_ID, ADDR_GOAL_POSITION, result)

    def close(self) -> None:
        self.port.closePort()
