"""Record trials: `python -m acquisition.record --fabric=12 --trials=6 --day=1 --out=DIR [--simulate]`.

Hardware: servos on --servo_port, Minsight on --camera (index or path), the Pi sender at
--pi_host:--pi_port; hold the fingers open at the start so the first frame is the no-contact
reference of the force proxy (gain and deadband from --force_gain / --force_deadband, calibrated
once against a load cell). With --simulate every device is a simulated one behind the real drivers,
driven by the scene simulator. Stops at the first failed or interrupted trial (its archive is kept,
marked complete=false) and exits non-zero.
"""

from __future__ import annotations

import sys
from pathlib import Path

from absl import app, flags

from acquisition import recorder

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


def hardware_rig() -> recorder.Rig:
    from acquisition.camera import Camera, ForceProxy
    from acquisition.mics import MicReceiver
    from acquisition.servos import ServoBus

    bus = ServoBus(FLAGS.servo_port)
    bus.ping_all()
    bus.set_torque(True)
    cam = Camera(int(FLAGS.camera) if FLAGS.camera.isdigit() else FLAGS.camera)
    force = ForceProxy(cam.read(), gain=FLAGS.force_gain, deadband=FLAGS.force_deadband)
    source = {"kind": "hardware", "servo_port": FLAGS.servo_port, "camera": FLAGS.camera, "pi": f"{FLAGS.pi_host}:{FLAGS.pi_port}"}
    return recorder.Rig(bus=bus, camera=cam, mics=MicReceiver(FLAGS.pi_host, FLAGS.pi_port), force=force, source=source)


def main(argv):
    del argv
    out = Path(FLAGS.out)
    for trial in range(FLAGS.first_trial, FLAGS.first_trial + FLAGS.trials):
        if FLAGS.simulate:
            from acquisition import sim_signals, simulated

            signals = sim_signals.trial_signals(FLAGS.fabric, FLAGS.day, trial, n_cycles=FLAGS.cycles, condition=FLAGS.condition)
            with simulated.simulated_rig(signals) as rig:
                rec = recorder.record_trial(rig, sim_signals.procedure(FLAGS.cycles), fabric_id=FLAGS.fabric, day=FLAGS.day,
                                            trial=trial, out_dir=out, condition=FLAGS.condition)
        else:
            from acquisition.procedure import ExploratoryProcedure

            rig = hardware_rig()
            try:
                rec = recorder.record_trial(rig, ExploratoryProcedure(n_cycles=FLAGS.cycles), fabric_id=FLAGS.fabric,
                                            day=FLAGS.day, trial=trial, out_dir=out, condition=FLAGS.condition)
            finally:
                rig.close()
        st = rec.archive.meta["step_time"]
        print(f"{rec.path}: {rec.archive.n_steps} steps, step p50 {st['p50_ms']} ms p99 {st['p99_ms']} ms, "
              f"missed {st['missed_deadlines']}" + (f", INCOMPLETE: {rec.failure}" if rec.failure else ""))
        if rec.failure:
            sys.exit(1)


if __name__ == "__main__":
    app.run(main)
