"""Fit each declared calibration's estimate to its measurement of the paper
(see fabricjax/studies/diagnostics/calibrate.py).

    python -m experiments.calibrate                     # into workspace/results/
    python -m experiments.calibrate --results=results   # regenerates results/calibration.md

Each point tried simulates the default preset (audio and joints) and trains the matched row: a few minutes a point
on a 2-core laptop, at most eight points; resumable (the points measured are kept under <workspace>/calibration/).
"""

from experiments import flags
from fabricjax.studies.diagnostics import calibrate


def main(argv):
    del argv
    calibrate.run(where=flags.location())


if __name__ == "__main__":
    flags.run(main)
