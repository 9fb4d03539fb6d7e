"""Raspberry Pi side: stream the two SPH0645 microphones to the laptop over TCP (format in `wire`).

python -m acquisition.pi_sender --port=5005 --device=hw:CARD=sndrpii2scard
python -m acquisition.pi_sender --port=5005 --simulate --fabric=12     # simulated words
"""

from absl import app, flags

from acquisition import wire

FLAGS = flags.FLAGS
flags.DEFINE_string("host", "0.0.0.0", "Address to listen on.")
flags.DEFINE_integer("port", 5005, "TCP port to listen on.")
flags.DEFINE_string("device", "hw:CARD=sndrpii2scard", "ALSA capture device of the I2S microphones.")
flags.DEFINE_bool("simulate", False, "Stream simulated SPH0645 words instead of arecord.")
flags.DEFINE_integer("fabric", 12, "Fabric of the simulated trial (with --simulate).")
flags.DEFINE_integer("cycles", 50, "Rubbing cycles of the simulated trial (with --simulate).")


def main(argv):
    del argv
    if FLAGS.simulate:
        from acquisition import simulated_devices, simulated_signals

        periods = simulated_devices.paced_periods(
            simulated_signals.trial_signals(FLAGS.fabric, n_cycles=FLAGS.cycles).audio
        )
        sent = wire.serve(periods, FLAGS.host, FLAGS.port)
    else:
        with wire.arecord_periods(FLAGS.device) as periods:
            sent = wire.serve(periods, FLAGS.host, FLAGS.port)
    print(
        f"pi_sender: {sent['ended']}; sent {sent['sent']} packets, dropped {sent['dropped']}, {sent['frames']} frames"
    )


if __name__ == "__main__":
    app.run(main)
