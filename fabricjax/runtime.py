"""Process-wide JAX setup, in one explicit call: `configure_jax(...)`.

Importing a `fabricjax` module changes nothing in JAX. Whoever starts a process calls
`configure_jax` once, before JAX computes anything: every command (`fabricjax.cli.run` calls it;
`experiments.flags.run` adds the CPU device count and the compilation cache), tests/conftest.py and
the tests' own training subprocesses. A program that uses the library without it computes the
same results, only its CPU training steps are slower (see `unroll_threefry_on_cpu`) and its
programs take longer to build (`compile_at_backend_level`).

What it sets:
* `distributed`: this process joins a run over several processes (hosts) first
  (`join_processes`), before JAX starts a backend;
* always: the unrolled `threefry2x32` lowering on CPU (`unroll_threefry_on_cpu`), and LLVM's
  optimisation level 2 for XLA's compiled code (`compile_at_backend_level`), which must come
  before JAX starts a backend;
* `cpu_devices`: JAX's CPU device count (`use_cpu_cores`; `available_cores()`: one per core), which
  must come before JAX starts its CPU backend; None leaves JAX's choice (one CPU device, or
  XLA_FLAGS / JAX_NUM_CPU_DEVICES);
* `compilation_cache_dir`: XLA's persistent compilation cache there (programs that took >= 1 s to
  compile), so a rerun of a study skips compilation.

JAX itself is imported inside the functions, so that `fabricjax.cli` can choose JAX's platforms
(JAX_PLATFORMS) before anything imports JAX.
"""

from __future__ import annotations

import os
import sys
import warnings
from typing import Any, Mapping

MIN_CACHED_COMPILE_S = 1.0  # programs compiling faster than this are not worth a cache file

# LLVM's optimisation level for the code XLA compiles (XLA's default: 3). Level 2 builds a
# training row's programs faster and they compute the same bits (a test trains under both
# levels); the default preset's steps run as fast, the paper model's 5-seed step a few per cent
# slower (README, Speed), so a long run may prefer level 3 through XLA_FLAGS.
BACKEND_OPTIMIZATION_LEVEL = 2
_LEVEL_FLAG = "--xla_backend_optimization_level"

_threefry_unrolled: bool | None = None


def unroll_threefry_on_cpu() -> bool:
    """Lower `threefry2x32` on CPU with the unrolled rounds JAX uses on other backends; returns
    whether that lowering is in place (idempotent).

    JAX's CPU lowering rolls the 20 rounds into a `while` loop (to save compile time), which runs
    as a chain of small unfused kernels, a visible share of a CPU training step for the dropout
    masks. The unrolled lowering is one fused kernel and yields the same bits (same function,
    only its lowering differs). Private JAX API: if it moves, keep JAX's default.
    """
    global _threefry_unrolled
    if _threefry_unrolled is None:
        try:
            from jax._src.interpreters import mlir
            from jax._src.random import threefry2x32 as tf

            mlir.register_lowering(tf.threefry2x32_p, tf._threefry2x32_lowering_rule, platform="cpu", inline=False)
            _threefry_unrolled = True
        except (ImportError, AttributeError, TypeError):  # pragma: no cover - depends on the JAX version
            _threefry_unrolled = False
    return _threefry_unrolled


def compile_at_backend_level(level: int = BACKEND_OPTIMIZATION_LEVEL) -> None:
    """Have XLA compile this process's programs (and its children's) with LLVM at `level`, through
    XLA_FLAGS, which XLA reads when JAX starts its backend; a level already in XLA_FLAGS wins."""
    flags = os.environ.get("XLA_FLAGS", "")
    if _LEVEL_FLAG not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} {_LEVEL_FLAG}={level}".strip()


def use_compilation_cache(directory: str | os.PathLike) -> None:
    """Keep XLA's compiled programs in `directory` (every study row is one program per config,
    whose compilation a rerun then skips)."""
    import jax

    jax.config.update("jax_compilation_cache_dir", str(directory))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_CACHED_COMPILE_S)


def join_processes(**initialize: Any) -> None:
    """Make this process one of a multi-process run: `jax.distributed.initialize(**initialize)`.

    Without arguments JAX reads the cluster's environment (SLURM, Open MPI, ...); outside a
    cluster scheduler give `coordinator_address` ("host:port" of process 0), `num_processes` and
    `process_id`. Afterwards `jax.devices()` lists every process's devices, so the training mesh
    (`sharding.training_mesh`) spans them all; on CPU the processes' collectives go over Gloo
    (JAX's default `jax_cpu_collectives_implementation`). Must come before JAX starts a backend."""
    import jax

    jax.distributed.initialize(**initialize)


def is_primary() -> bool:
    """Whether this process writes the files every process would write alike (results, figures,
    training curves): process 0 of a multi-process run, and any process that joined none (asked
    without importing JAX or starting a backend)."""
    jax = sys.modules.get("jax")
    return jax is None or not jax.distributed.is_initialized() or jax.process_index() == 0


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity): one CPU device each for training."""
    return len(os.sched_getaffinity(0))


def use_cpu_cores(n: int | None = None) -> int:
    """Expose `n` CPU devices (default: one per core this process may run on); returns the count.

    Only possible before JAX starts its CPU backend (before any JAX computation); a count already
    chosen with XLA_FLAGS=--xla_force_host_platform_device_count or JAX_NUM_CPU_DEVICES wins. A
    count of 1 keeps the single device."""
    import jax

    if "xla_force_host_platform_device_count" in os.environ.get("XLA_FLAGS", "") or os.environ.get(
        "JAX_NUM_CPU_DEVICES"
    ):
        return len(jax.devices("cpu"))
    n = n or available_cores()
    try:
        jax.config.update("jax_num_cpu_devices", n)
    except RuntimeError:  # JAX has started
        if len(jax.devices("cpu")) != n:
            warnings.warn(
                f"JAX already started with {len(jax.devices('cpu'))} CPU device(s); use_cpu_cores({n}) comes too late"
            )
    return len(jax.devices("cpu"))


def configure_jax(
    *,
    cpu_devices: int | None = None,
    compilation_cache_dir: str | os.PathLike | None = None,
    distributed: Mapping[str, Any] | None = None,
) -> None:
    """The process's JAX setup (see the module docstring); call it before JAX computes anything.
    `distributed`: the keyword arguments of `join_processes` ({} for a cluster's environment),
    None for a run in this process alone."""
    compile_at_backend_level()
    if distributed is not None:
        join_processes(**distributed)
    unroll_threefry_on_cpu()
    if cpu_devices is not None:
        use_cpu_cores(cpu_devices)
    if compilation_cache_dir is not None:
        use_compilation_cache(compilation_cache_dir)
