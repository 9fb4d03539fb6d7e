"""Record trials: `python -m acquisition.record --fabric=12 --trials=6 --day=1 --out=DIR [--simulate]`.

Hardware: servos on --servo_port, Minsight on --camera (index or path), the Pi sender at
--pi_host:--pi_port. Hold the fingers open at the start of each trial: the camera's no-contact
reference is taken then, as Minsight's own camera node takes it (its warm-up frames discarded),
but of --reference_frames frames (default `archive.REFERENCE_FRAMES`, averaged where they are
read) where Minsight's node keeps one. It is stored in the trial's archive, and the force proxy
reads against the frames' mean (gain and deadband from --force_gain / --force_deadband, calibrated
once against a load cell). The camera runs on fixed exposure and white balance
(`acquisition.camera.controls_for`): what it reads back goes into meta.source.camera_controls, and
a control it refuses is one logged line. With --simulate every device is a simulated one behind
the real drivers, driven by the scene simulator. Stops at the first failed or interrupted trial
(its archive is kept, marked complete=false) and exits non-zero.

--view streams each step to the Rerun viewer as it is recorded (--view_save=FILE.rrd: to a
recording instead; `pip install -e ".[viz]"`), the same entities as `experiments.view`; with
--checkpoint (a streamable model) also the running prediction, its confidence and each step's
latency. Viewing runs in the recording loop after each step's work: its cost shows in the
archive's step-time statistics as lateness, so record the dataset without it.
"""

from __future__ import annotations

import queue
import sys
import threading
import time
from pathlib import Path

import numpy as np
from absl import flags

from acquisition import recorder
from acquisition.camera import IMAGE_SIZE
from fabricjax import cli
from fabricjax.errors import UserError
from fabricjax.store import archive

FLAGS = flags.FLAGS
flags.DEFINE_integer("fabric", None, "Fabric id (0 = no fabric).", required=True)
flags.DEFINE_integer("trials", 6, "Number of trials.")
flags.DEFINE_integer("first_trial", 0, "Index of the first trial.")
flags.DEFINE_integer("day", 1, "Recording day.")
flags.DEFINE_enum("condition", "lab", ["lab", "cafe"], "Acoustic condition.")
flags.DEFINE_integer("cycles", 50, "Rubbing cycles per trial.")
flags.DEFINE_string("out", None, "Folder of the dataset's trial archives.", required=True)
flags.DEFINE_bool("simulate", False, "Use simulated devices driven by the scene simulator.")
flags.DEFINE_string("servo_port", "/dev/ttyUSB0", "Serial port of the servo bus.")
flags.DEFINE_string("camera", "0", "Minsight camera: device index or path.")
flags.DEFINE_string("pi_host", "raspberrypi.local", "Host of the Pi sender.")
flags.DEFINE_integer("pi_port", 5005, "Port of the Pi sender.")
flags.DEFINE_float("force_gain", 0.05, "Force proxy gain, N per grey level of mean difference.")
flags.DEFINE_float("force_deadband", 0.5, "Force proxy deadband, grey levels.")
flags.DEFINE_integer(
    "reference_frames",
    archive.REFERENCE_FRAMES,
    "No-contact frames of the camera's reference, taken after its warm-up with the fingers open (averaged where read).",
    lower_bound=1,
    upper_bound=archive.MAX_REFERENCE_FRAMES,
)
flags.DEFINE_bool("view", False, "Stream each step to the Rerun viewer as it is recorded.")
flags.DEFINE_string("view_save", None, "Log what --view shows to this .rrd file instead.")
flags.DEFINE_string(
    "checkpoint", None, "With --view / --view_save: a streamable model whose running prediction is shown."
)


def hardware_rig(session: str) -> recorder.Rig:
    """The hand's devices, opened; the fingers must be open: the camera's no-contact reference of
    `session` is taken now (`camera.take_reference`), and the force proxy reads against it."""
    from acquisition.camera import Camera, take_reference
    from acquisition.mics import MicReceiver
    from acquisition.servos import ServoBus
    from fabricjax.force_proxy import ForceProxy

    bus = ServoBus(FLAGS.servo_port)
    bus.ping_all()
    bus.set_torque(True)
    cam = Camera(int(FLAGS.camera) if FLAGS.camera.isdigit() else FLAGS.camera)
    reference = take_reference(cam, session, FLAGS.reference_frames)
    force = ForceProxy(reference.mean_frame(), gain=FLAGS.force_gain, deadband=FLAGS.force_deadband)
    source = {
        "kind": "hardware",
        "servo_port": FLAGS.servo_port,
        "camera": FLAGS.camera,
        "camera_controls": cam.controls,
        "pi": f"{FLAGS.pi_host}:{FLAGS.pi_port}",
    }
    return recorder.Rig(
        bus=bus,
        camera=cam,
        mics=MicReceiver(FLAGS.pi_host, FLAGS.pi_port),
        force=force,
        source=source,
        reference=reference,
    )


class Watcher:
    """--view / --view_save for one trial: `on_step` (the `on_step` of `recorder.record_trial`)
    hands each step to a thread that logs it (`fabricjax.inference.view.TrialView`) and, with a model, runs
    the streaming classifier on it, so the 50 Hz loop only pays for a queue put. A viewer that
    falls `BACKLOG` steps behind drops the newest steps (counted in `dropped`) rather than hold
    the trial's frames in memory."""

    BACKLOG = 250  # 5 s of steps

    def __init__(self, view, live, streamer, save):
        self.view, self.live, self.streamer = view, live, streamer
        self.rec = view.open_recording(save)
        self.viewer = view.TrialView(self.rec, FLAGS.fabric)
        self.viewer.warmup(IMAGE_SIZE)
        if streamer is not None:
            streamer.reset()
        self.queue = queue.Queue(self.BACKLOG)
        self.dropped = 0
        self.thread = threading.Thread(target=self._work, daemon=True)
        self.thread.start()

    def on_step(self, **fields) -> None:
        step = self.view.Step(**{k: v.copy() if isinstance(v, np.ndarray) else v for k, v in fields.items()})
        try:
            self.queue.put_nowait(step)
        except queue.Full:
            self.dropped += 1

    def _work(self) -> None:
        while (step := self.queue.get()) is not None:
            self.viewer.log_step(step)
            if self.streamer is not None:
                t0 = time.perf_counter()
                probs = self.streamer.update(step.windows[self.streamer.mics], step.joints)
                self.viewer.log_prediction(
                    self.live.StepResult(step.index, step.time_s, probs, 1e3 * (time.perf_counter() - t0))
                )

    def close(self) -> None:
        """Log the backlog, then flush the recording."""
        self.queue.put(None)
        self.thread.join()
        self.rec.flush()


def watcher():
    """A function of the trial index giving its `Watcher`, or None without --view / --view_save.
    Each trial is its own recording (with several --trials, --view_save=x.rrd writes x_trial<k>.rrd)."""
    if FLAGS.checkpoint and not (FLAGS.view or FLAGS.view_save):
        raise UserError("--checkpoint shows a model's predictions in the viewer: add --view or --view_save")
    if not (FLAGS.view or FLAGS.view_save):
        return None
    from fabricjax.inference import live, view

    if not FLAGS.view_save:
        view.require_display("--view_save")
    streamer = None
    if FLAGS.checkpoint:
        streamer = live.Streamer(*live.restore_model(FLAGS.checkpoint))
        streamer.warmup()

    def for_trial(trial: int) -> Watcher:
        save = None
        if FLAGS.view_save:
            save = Path(FLAGS.view_save)
            save = save if FLAGS.trials == 1 else save.with_name(f"{save.stem}_trial{trial}{save.suffix}")
        return Watcher(view, live, streamer, save)

    return for_trial


def main(argv):
    del argv
    out = Path(FLAGS.out)
    watch = watcher()
    for trial in range(FLAGS.first_trial, FLAGS.first_trial + FLAGS.trials):
        watching = watch(trial) if watch is not None else None
        on_step = watching.on_step if watching is not None else None
        try:
            if FLAGS.simulate:
                from acquisition import simulated_devices, simulated_signals

                signals = simulated_signals.trial_signals(
                    FLAGS.fabric, FLAGS.day, trial, n_cycles=FLAGS.cycles, condition=FLAGS.condition
                )
                with simulated_devices.simulated_rig(signals) as rig:
                    rec = recorder.record_trial(
                        rig,
                        simulated_signals.procedure(FLAGS.cycles),
                        fabric_id=FLAGS.fabric,
                        day=FLAGS.day,
                        trial=trial,
                        out_dir=out,
                        condition=FLAGS.condition,
                        on_step=on_step,
                    )
            else:
                from acquisition.procedure import ExploratoryProcedure

                rig = hardware_rig(f"day{FLAGS.day}_{FLAGS.condition}_trial{trial}")
                try:
                    rec = recorder.record_trial(
                        rig,
                        ExploratoryProcedure(n_cycles=FLAGS.cycles),
                        fabric_id=FLAGS.fabric,
                        day=FLAGS.day,
                        trial=trial,
                        out_dir=out,
                        condition=FLAGS.condition,
                        on_step=on_step,
                    )
                finally:
                    rig.close()
        finally:  # on an error too: the viewer's thread ends and the recording is flushed
            if watching is not None:
                watching.close()
        if watching is not None and watching.dropped:
            print(f"view: {watching.dropped} steps dropped (the viewer fell {Watcher.BACKLOG} steps behind)")
        st = rec.archive.meta["step_time"]
        print(
            f"{rec.path}: {rec.archive.n_steps} steps, step p50 {st['p50_ms']} ms p99 {st['p99_ms']} ms, "
            f"missed {st['missed_deadlines']}" + (f", INCOMPLETE: {rec.failure}" if rec.failure else "")
        )
        if rec.failure:
            sys.exit(1)


if __name__ == "__main__":
    cli.run(main)
