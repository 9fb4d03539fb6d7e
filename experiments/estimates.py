"""The simulator's estimates (fabricjax/sim/estimates.py) as a table in docs/simulator.md.

    python -m experiments.estimates           # rewrites the block between the table's markers
    python -m experiments.estimates --check   # exits 1 if the block differs from the registry

Each estimate with its value, declared range, scale, streams, the reason for its range and what it
drives, grouped by the sensitivity study's factors.
"""

from __future__ import annotations

import sys
from pathlib import Path

from absl import flags

from fabricjax import cli
from fabricjax.sim import estimates
from fabricjax.store import provenance

FLAGS = flags.FLAGS
flags.DEFINE_bool("check", False, "only compare: exit 1 if the document's block differs from the registry")
DOC = Path("docs") / "simulator.md"  # in the repository
flags.DEFINE_string("doc", None, f"the document holding the table's markers (default: the repository's {DOC})")


def main(argv):
    del argv
    path = Path(FLAGS.doc) if FLAGS.doc else provenance.repository_root() / DOC
    text = path.read_text()
    try:
        new = estimates.with_table(text)
    except ValueError as e:
        cli.fail(f"{path}: {e}")
    if FLAGS.check:
        if new != text:
            print(
                f"{path}: the estimates table differs from fabricjax/sim/estimates.py; run python -m "
                f"experiments.estimates",
                file=sys.stderr,
            )
            sys.exit(1)
        print(f"{path}: the estimates table is up to date ({len(estimates.ESTIMATES)} estimates)")
        return
    if new != text:
        path.write_text(new)
    print(
        f"{path}: {len(estimates.ESTIMATES)} estimates in {len(estimates.GROUPS)} groups"
        + ("" if new != text else " (unchanged)")
    )


if __name__ == "__main__":
    cli.run(main, before=lambda: None)
