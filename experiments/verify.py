"""Check a dataset: `python -m experiments.verify DIR`.

Re-hashes every archive against the sha256 its index recorded (the index that `import_manifest`,
or the first study reading DIR, wrote in the workspace `--workdir`; without one it says so and
hashes nothing), re-validates every field and reports irregular step timestamps
(`fabricjax.store.integrity`); prints each problem as `file: field: reason` and exits 1 if there is any.
Every file is checked whatever another holds; a file verify itself fails on (a bug, not a finding
about the data) is printed with the exception, and the exit status is then 2, as for any error of
the command. Writes nothing, in DIR or elsewhere."""

from __future__ import annotations

import sys

from absl import flags

from fabricjax import cli
from fabricjax.errors import UserError
from fabricjax.store import integrity

FLAGS = flags.FLAGS
flags.DEFINE_string("workdir", None, "Workspace whose index of DIR to check against (default: the usual workspace).")


def main(argv):
    if len(argv) != 2:
        raise UserError("give exactly one dataset folder: python -m experiments.verify DIR")
    problems, counts = integrity.verify(argv[1], FLAGS.workdir)
    for p in problems:
        print(p)
    hashed = (
        f"{counts['hashed']} hashed against {counts['index']}"
        if counts["index"]
        else f"no index of {argv[1]} in this workspace, so no hashes to check: import_manifest and the first "
        f"study reading it write one"
    )
    print(
        f"{counts['archives']} archives checked ({hashed}): {len(problems) or 'no'} problem{'s' * (len(problems) != 1)}"
    )
    for f in counts["failures"]:
        print(f)
    if counts["failures"]:
        print(
            f"verify failed on {len(counts['failures'])} file{'s' * (len(counts['failures']) != 1)} (a bug "
            f"of verify: the lines above name them)",
            file=sys.stderr,
        )
        sys.exit(2)
    if problems:
        sys.exit(1)


if __name__ == "__main__":
    cli.run(main)
