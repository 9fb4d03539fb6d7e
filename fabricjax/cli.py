"""How every command starts and ends, whatever its flags.

* JAX's setup: `fabricjax.runtime.configure_jax` runs after the flags are parsed and before the
  command's work (`before`; a command that sets more, such as its CPU devices, passes its own call).
* JAX's platforms: with JAX_PLATFORMS unset and no accelerator plugin installed, JAX would probe
  for a TPU and log the failure ("Unable to initialize backend 'tpu' ... libtpu.so") as the first
  line a user sees; such a machine can only be a CPU, so the CPU is chosen. With a CUDA, ROCm or
  TPU plugin installed, or JAX_PLATFORMS set, JAX chooses as usual: a real GPU is never hidden.
* `--help` lists the project's own flags (those of the command and of `experiments.flags`), not
  absl's, orbax's and JAX's (`--helpfull` still shows everything), under the command as a user
  runs it (`python -m experiments.ablation`), and exits 0.
* Log lines: INFO lines of other libraries (orbax's per-save lines, absl's) are dropped unless
  `--verbosity` is given; warnings always show. Log lines go out through `tqdm.write`, so they never
  share a line with a progress bar (the bar is cleared, the line written, the bar redrawn).
* A user's mistake (a bad flag value, or a `fabricjax.errors.UserError` such as a damaged archive,
  an empty data folder or an unknown row) ends in one line `error: <message>` on stderr and exit
  status 2; `--verbosity=1` (absl's debug level) shows its traceback. So does a full disk, also
  where a library's write found it (`fabricjax.store.disk`). Anything else is a bug and keeps its
  traceback.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import logging as std_logging
import os
import shlex
import sys
from typing import Callable, Mapping, Sequence

from absl import app, flags, logging
from tqdm import tqdm

from fabricjax import runtime
from fabricjax.errors import UserError
from fabricjax.store import disk, provenance, workspace

FLAGS = flags.FLAGS
USER_ERROR_STATUS = 2
HELP_ARGS = ("--help", "-help", "--helpshort", "-helpshort", "-h", "-?")
PROJECT_PACKAGES = ("experiments", "acquisition", "fabricjax")
TPU_LIBRARIES = ("libtpu",)  # JAX's TPU runtime, which it probes for without a plugin entry point


def accelerator_plugins() -> list[str]:
    """The installed JAX accelerator plugins (jax[cuda12], ROCm, TPU), by name."""
    names = [ep.name for ep in importlib.metadata.entry_points(group="jax_plugins")]
    return names + [m for m in ("jax_plugins", *TPU_LIBRARIES) if importlib.util.find_spec(m) is not None]


def default_platforms(environ: Mapping[str, str], plugins: Sequence[str]) -> str | None:
    """The JAX_PLATFORMS to set: "cpu" when it is unset and no accelerator plugin is installed,
    else None (leave the choice to JAX)."""
    return None if environ.get("JAX_PLATFORMS") or plugins else "cpu"


def choose_platforms() -> None:
    """Set JAX_PLATFORMS (see `default_platforms`) for this process, before its backends start,
    and for the processes it spawns (simulation and feature pools)."""
    platforms = default_platforms(os.environ, accelerator_plugins())
    if platforms is None:
        return
    os.environ["JAX_PLATFORMS"] = platforms
    if "jax" in sys.modules:  # imported already: its config read the environment at import
        sys.modules["jax"].config.update("jax_platforms", platforms)


def fail(message: str) -> None:
    """The end of a command the user asked for wrongly: one line on stderr, status 2."""
    print(f"error: {message}", file=sys.stderr)
    sys.exit(USER_ERROR_STATUS)


def project_flags() -> list[flags.Flag]:
    """The flags defined by this project's modules (the command's own and experiments.flags')."""
    main = sys.argv[0]
    return [
        f
        for module, defined in FLAGS.flags_by_module_dict().items()
        if module == main or module.split(".")[0] in PROJECT_PACKAGES
        for f in defined
    ]


def usage() -> None:
    """absl's short help, the command's docstring and then its flags, with the flags headed by the
    command as a user runs it (`python -m experiments.ablation`): absl heads them with the main
    module's absolute path, which names this machine's folders and no command a user could type."""
    main, shown = sys.argv[0], shlex.join(provenance.program())
    for f in project_flags():
        FLAGS.register_key_flag_for_module(main, f)
    doc = sys.modules["__main__"].__doc__ or f"\nUSAGE: {shown} [flags]\n"
    print(f"{doc}\nflags:\n{FLAGS.module_help(main).replace(f'{main}:', f'{shown}:', 1)}")
    print("\nFlags of absl, JAX and orbax (logging, verbosity, ...): --helpfull")


def _parse(argv: list[str]) -> list[str]:
    """absl's flag parsing, with `--help` listing the project's flags (`usage`, exit 0) and a bad
    flag value reported as a user error."""
    if any(a in HELP_ARGS for a in argv[1:]):
        usage()
        sys.exit(0)
    try:
        return FLAGS(argv)
    except flags.Error as e:
        fail(f"{e} (--help lists the flags)")


class _BelowProgressBars:
    """A stream for log lines that writes them through `tqdm.write`, above any active progress bar."""

    def write(self, text: str) -> None:
        tqdm.write(text, file=sys.stderr, end="")

    def flush(self) -> None:
        sys.stderr.flush()

    def close(self) -> None:
        """At exit, logging closes its handlers' streams: stderr stays open."""


_PROJECT_DIRS = tuple(os.path.join(provenance.repository_root(), p) + os.sep for p in PROJECT_PACKAGES)


def _shown(record: std_logging.LogRecord) -> bool:
    """Without --verbosity: warnings and errors, and the project's own INFO lines."""
    return (
        record.levelno >= std_logging.WARNING
        or os.path.abspath(record.pathname).startswith(_PROJECT_DIRS)
        or (record.pathname == sys.argv[0])
    )


def quiet_logs() -> None:
    """The log setup of the module docstring: other libraries' INFO lines off unless --verbosity
    asks, every line written above the progress bars."""
    handler = logging.get_absl_handler()
    handler.python_handler.stream = _BelowProgressBars()
    if not FLAGS["verbosity"].present:
        handler.addFilter(_shown)


def run(main: Callable[[list[str]], object], before: Callable[[], None] = runtime.configure_jax) -> None:
    """`absl.app.run(main)` as described in the module docstring; `before` runs after the flags
    are parsed and before `main`: the process's JAX setup (`runtime.configure_jax`, or a call of it
    with the command's CPU devices and compilation cache, which must come before JAX starts)."""
    choose_platforms()

    def start(argv):
        quiet_logs()
        before()
        try:
            return main(argv)
        except UserError as e:
            if logging.get_verbosity() >= logging.DEBUG:
                raise
            fail(str(e))
        except Exception as e:  # a library's own write on a full disk: the same one line as ours
            if not disk.is_full(e) or logging.get_verbosity() >= logging.DEBUG:
                raise
            workdir = FLAGS["workdir"].value if "workdir" in FLAGS else None
            path = disk.full_path(e) or workspace.root(workdir).absolute()  # a library that did not say which file
            fail(str(disk.DiskFull(path, "a file")))

    app.run(start, flags_parser=_parse)
