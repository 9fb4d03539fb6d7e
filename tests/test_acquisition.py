"""Acquisition against simulated devices: the real scservo_sdk over a pty, cv2.VideoCapture over a
video file, TCP on 127.0.0.1. Trials are short (2-3 rubbing cycles)."""

import dataclasses
import os
import random
import re
import signal

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from acquisition import mics, recorder, servos, simulated_devices, simulated_signals, wire
from fabricjax.store import archive


@pytest.fixture(scope="module")
def signals():
    return simulated_signals.trial_signals(12, day=1, trial=0, n_cycles=2)


def test_wire_rate_is_the_archive_rate():
    assert wire.RATE == archive.AUDIO_RATE  # wire.py cannot import fabricjax: it runs on a bare Pi


def test_sign_magnitude_round_trip():
    for v, bit in [(0, 15), (1234, 15), (-1234, 15), (-1, 10), (1023, 10)]:
        assert servos.sign_magnitude(servos.encode_sign_magnitude(v, bit), bit) == v
    assert servos.angle_to_counts(0.0) == 2048
    assert servos.sign_magnitude(0x8000 | 5, 15) == -5


def test_sdk_round_trip_over_pty(signals):
    sim = simulated_devices.SimServoBus(signals.joints).start()
    bus = servos.ServoBus(sim.path)
    try:
        assert bus.ping_all() == {i: servos.STS3215_MODEL for i in servos.DEFAULT_IDS}
        bus.set_torque(True)
        assert all(sim.memory[i][servos.ADDR_TORQUE_ENABLE] == 1 for i in servos.DEFAULT_IDS)
        for k in range(3):
            state = bus.read_state()
            want = signals.joints[k]
            np.testing.assert_allclose(state[:, 0], want[:, 0], atol=servos.RAD_PER_COUNT)
            np.testing.assert_allclose(state[:, 1], want[:, 1], atol=servos.RAD_PER_COUNT)
            np.testing.assert_allclose(state[:, 2], want[:, 2], atol=servos.AMP_PER_COUNT)
        goals = np.linspace(-0.5, 0.5, 6)
        bus.write_goals(goals)
        bus.ping_all()  # a reply after the broadcast: the goals have been processed
        got = [int.from_bytes(sim.memory[i][42:44], "little") for i in servos.DEFAULT_IDS]
        assert got == [servos.angle_to_counts(g) for g in goals]
    finally:
        bus.close()
        assert sim.stop() == {"sync_reads": 3, "goal_writes": 1}


def test_silent_servo_is_a_clear_error(signals):
    sim = simulated_devices.SimServoBus(signals.joints, faults=simulated_devices.Faults(silent_servo=(5, 1))).start()
    bus = servos.ServoBus(sim.path, retries=1)
    try:
        bus.read_state()
        with pytest.raises(
            servos.ServoError, match=r"servo 5 \(middle_tip\), register present position..current \(56..70\)"
        ):
            bus.read_state()
    finally:
        bus.close()
        sim.stop()


def test_corrupt_checksums_are_retried_then_reported(signals):
    sim = simulated_devices.SimServoBus(
        signals.joints, faults=simulated_devices.Faults(corrupt_servo=(3, 2, 3))
    ).start()
    bus = servos.ServoBus(sim.path, retries=2)
    try:
        for _ in range(8):  # every third sync read is garbled: each one is retried successfully
            bus.read_state()
        assert bus.retried >= 2
    finally:
        bus.close()
        sim.stop()
    sim = simulated_devices.SimServoBus(
        signals.joints, faults=simulated_devices.Faults(corrupt_servo=(3, 1, 1))
    ).start()
    bus = servos.ServoBus(sim.path, retries=2)
    try:
        with pytest.raises(servos.ServoError, match=r"servo 3 \(thumb_tip\).*Incorrect status packet.*3 tries"):
            bus.read_state()
    finally:
        bus.close()
        sim.stop()


def _packets(frames: np.ndarray, sizes) -> tuple[bytes, int]:
    out, start, seq = b"", 0, 0
    for n in sizes:
        chunk = frames[start : start + n]
        out += wire.HEADER.pack(wire.MAGIC, seq, start, len(chunk)) + chunk.astype("<i4").tobytes()
        start, seq = start + len(chunk), seq + 1
    return out, start


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(1, 700), min_size=1, max_size=12), st.integers(0, 2**31 - 1))
def test_reframing_whatever_the_chunking(sizes, seed):
    rng = np.random.default_rng(seed)
    frames = rng.integers(-(2**31), 2**31 - 1, size=(sum(sizes), 2), dtype=np.int64).astype(np.int32)
    stream, total = _packets(frames, sizes)
    cuts = sorted(random.Random(seed).sample(range(1, len(stream)), min(len(stream) - 1, 20)))
    assembler, ring, got = mics.FrameAssembler(), mics.RingBuffer(capacity=1024), []
    for a, b in zip([0, *cuts], [*cuts, len(stream)]):  # chunks end mid-header and mid-sample
        for _, first, part in assembler.feed(stream[a:b]):
            assert first == sum(len(g) for g in got)
            got.append(part)
            ring.write(part)
    np.testing.assert_array_equal(np.concatenate(got), frames)
    assert ring.end == total
    n = min(total, 700)
    np.testing.assert_array_equal(ring.latest(n), frames[-n:].T)


def test_bad_magic_is_a_clear_error():
    with pytest.raises(mics.MicError, match="out of sync"):
        mics.FrameAssembler().feed(b"\x00" * 40)


def _record(signals, faults, tmp_path, cycles=2):
    # Margins for a loaded machine, where the simulated devices run slower than real time: more
    # servo retries than the recorder's default (the simulated bus's process can answer after the
    # SDK's packet timeout three times running), and a longer closing allowance (the procedure's
    # clock is wall time, the simulated frames advance per read, so the force crosses 0.1 N later
    # than 4 s). Otherwise a spurious ServoError or ProcedureError ends a trial whose test is
    # about another device's fault.
    procedure = dataclasses.replace(simulated_signals.procedure(cycles), max_close_s=30.0)
    with simulated_devices.simulated_rig(signals, faults, servo_retries=5) as rig:
        rec = recorder.record_trial(rig, procedure, fabric_id=12, day=1, trial=0, out_dir=tmp_path)
    return rec, archive.read_archive(rec.path), rig.source["device_stats"]


def test_simulated_trial_through_sdk_opencv_and_tcp(signals, tmp_path):
    rec, arch, stats = _record(signals, simulated_devices.Faults(tcp_chunks=True, seed=3), tmp_path)
    meta = arch.meta
    assert rec.failure is None and meta["complete"] is True
    assert 0 < meta["closing_steps"] < arch.n_steps
    assert stats["servos"]["sync_reads"] == arch.n_steps + 1  # + the step that found the procedure done
    assert stats["servos"]["goal_writes"] == arch.n_steps
    # the raw stream arrives bit-exact through random TCP chunking, at its absolute position
    start = meta["mic_stream"]["start_index"]
    sent = signals.audio[:, start : start + arch.audio.shape[1]]  # a slow loop may run into the Pi's tail
    np.testing.assert_array_equal(arch.audio[:, : sent.shape[1]], sent)
    assert arch.window_end.min() >= archive.WINDOW
    np.testing.assert_allclose(arch.joints, signals.joints[: arch.n_steps], atol=servos.RAD_PER_COUNT)
    assert arch.images.shape[1:] == (308, 410, 3)
    # JPEG round trip: the wall's flake grain at mid-scale is fine, bright detail the codec rounds by several DN
    assert np.abs(arch.images.astype(float) - signals.images[: arch.n_steps]).mean() < 10
    assert arch.force[meta["closing_steps"]] >= 0.1 > arch.force[0]  # the step that stopped the closing
    # the session's no-contact reference, through the same codec, as the force proxy read it
    assert arch.reference.shape == (1, 308, 410, 3) and meta["reference"]["session"] == "day1_lab"
    assert np.abs(arch.reference[0].astype(float) - signals.reference).mean() < 10
    assert {"p50_ms", "p99_ms", "missed_deadlines"} <= set(meta["step_time"])


@pytest.mark.parametrize(
    "faults, failure",
    [
        (simulated_devices.Faults(drop_connection_after=70), "MicError: Pi sender .* closed the connection"),
        (simulated_devices.Faults(camera_stops_after=20), "CameraError: camera .* no frame after"),
        (simulated_devices.Faults(silent_servo=(2, 20)), r"ServoError: servo 2 \(thumb_mid\)"),
    ],
)
def test_device_failure_keeps_an_incomplete_archive(signals, tmp_path, faults, failure):
    rec, arch, _ = _record(signals, faults, tmp_path)
    # the steps before the fault are kept; how many depends on the machine's load (the Pi's
    # stream runs in real time, the simulated camera's steps slow down under load)
    assert arch.meta["complete"] is False and arch.n_steps > 0
    assert re.search(failure, arch.meta["failure"])
    assert rec.failure == arch.meta["failure"]


def test_recoverable_faults_are_counted(signals, tmp_path):
    _, arch, _ = _record(
        signals,
        simulated_devices.Faults(repeat_frames_every=10, drop_periods_every=25, corrupt_servo=(4, 5, 20)),
        tmp_path,
    )
    meta = arch.meta
    assert meta["complete"] is True, meta.get("failure")
    assert meta["camera_dropped_frames"] > 0
    assert meta["mic_stream"]["dropped_frames"] >= wire.PERIOD
    assert meta["servo_retries"] > 0


def test_ctrl_c_keeps_an_incomplete_archive(signals, tmp_path):
    with simulated_devices.simulated_rig(signals) as rig:
        # A real SIGINT, sent at the 10th frame (a wall-clock timer raced the 1-s procedure under load).
        read, calls = rig.camera.read, []

        def read_then_interrupt():
            calls.append(1)
            if len(calls) == 10:
                os.kill(os.getpid(), signal.SIGINT)
            return read()

        rig.camera.read = read_then_interrupt
        # Python's own Ctrl-C handler, as in a terminal (a shell starts background jobs with SIGINT ignored).
        previous = signal.signal(signal.SIGINT, signal.default_int_handler)
        try:
            with pytest.raises(KeyboardInterrupt, match="complete=False"):
                recorder.record_trial(
                    rig, simulated_signals.procedure(2), fabric_id=12, day=1, trial=4, out_dir=tmp_path
                )
        finally:
            signal.signal(signal.SIGINT, previous)
    (path,) = tmp_path.glob("*.npz")
    arch = archive.read_archive(path)
    assert arch.meta["complete"] is False and arch.meta["failure"] == "interrupted (Ctrl-C)"
    assert len(arch.timestamps) == 9  # the steps before the interrupted one
    assert not list(tmp_path.glob(".*partial"))


def test_recorded_features_match_the_simulators_direct_path(tmp_path):
    """What acquisition records is what the simulator writes: the same scene gives the same
    Minsound spectrum, and a recorded trial is nearest to its own fabric among direct-path trials."""
    from fabricjax import sim
    from fabricjax.features import extract

    def mean_psd(trial):
        return extract.log_psd(extract.mic_windows(trial, 0)).mean(axis=0)[:320]

    fabrics = (4, 6)  # smooth synthetic, knitted wool hat
    direct = {f: mean_psd(sim.simulate(sim.Scene(fabric_id=f, day=2, trial=1, cycles=2))) for f in fabrics}
    for f in fabrics:
        signals = simulated_signals.trial_signals(f, day=1, trial=0, n_cycles=2)
        with simulated_devices.simulated_rig(signals) as rig:
            rec = recorder.record_trial(
                rig, simulated_signals.procedure(2), fabric_id=f, day=1, trial=0, out_dir=tmp_path / str(f)
            )
        recorded = mean_psd(archive.read_archive(rec.path, images=False))
        same_scene = mean_psd(sim.simulate(sim.Scene(fabric_id=f, day=1, trial=0, cycles=2)))
        assert np.abs(recorded - same_scene).mean() < 0.3  # log10 units: windows fall at other instants
        nearest = min(fabrics, key=lambda g: np.linalg.norm(recorded - direct[g]))
        assert nearest == f
