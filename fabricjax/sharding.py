"""Data parallelism over seeds and minibatch samples: one code path for one CPU, one GPU or many devices.

Every training array carries a leading seed axis (`jax.vmap(..., spmd_axis_name=SEED)`). The mesh
has two axes. "seed" splits independent seeds over devices: no communication, the data is
replicated. "batch" splits every minibatch's samples over the devices the seed count cannot use
evenly (5 seeds on 2 devices, or 1 seed); XLA then sums each step's gradients over them with an
all-reduce, so results equal a one-device run up to the order of float summation.

A CPU is one device by default; `use_cpu_cores` makes it one device per core (the training and
benchmark commands call it first, through `runtime.configure_jax`), so that seeds or samples run
on separate cores instead of sharing each op. A single prediction answers faster on a one-device
CPU, whose ops use every core (README's speed section), so latency-bound commands keep one device.

In a run over several processes (`runtime.join_processes`) `jax.devices()` lists every process's
devices, so the mesh spans them all: host values go onto it with `put`, and what training returns
is replicated on every device (the "seed" axis has size 1), so every process reads it whole with
`jax.device_get`.
"""

from __future__ import annotations

import os
import warnings

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec as P

from fabricjax import runtime

SEED, BATCH = "seed", "batch"


def use_cpu_cores(n: int | None = None) -> int:
    """Expose `n` CPU devices (default: one per core this process may run on); returns the count.

    Only possible before JAX starts its CPU backend (before any JAX computation); a count already
    chosen with XLA_FLAGS=--xla_force_host_platform_device_count or JAX_NUM_CPU_DEVICES wins. A
    count of 1 keeps the single device."""
    if "xla_force_host_platform_device_count" in os.environ.get("XLA_FLAGS", "") or os.environ.get("JAX_NUM_CPU_DEVICES"):
        return len(jax.devices("cpu"))
    n = n or runtime.available_cores()
    try:
        jax.config.update("jax_num_cpu_devices", n)
    except RuntimeError:  # JAX has started
        if len(jax.devices("cpu")) != n:
            warnings.warn(f"JAX already started with {len(jax.devices('cpu'))} CPU device(s); use_cpu_cores({n}) comes too late")
    return len(jax.devices("cpu"))


def training_mesh(n_seeds: int, batch_size: int = 1) -> Mesh:
    """("seed", "batch") mesh: every minibatch's samples are split over the largest device count
    that divides `batch_size`; the seeds stay together on each device ("seed" has size 1).

    The layout depends on the batch size and the devices, never on the seed count, so a seed's
    result does not depend on how many seeds train beside it (tested). Splitting seeds over
    devices instead (no all-reduce) was up to ~10 % faster per step for even seed counts, but it
    changed the float summation order of a seed's gradients with the seed count, and with it the
    trained model."""
    devices = jax.devices()
    del n_seeds  # deliberately unused: see the docstring
    seeds = 1
    batch = max(d for d in range(1, len(devices) + 1) if batch_size % d == 0)
    return Mesh(np.asarray(devices[: seeds * batch]).reshape(seeds, batch), (SEED, BATCH))


def vmap_seeds(f, **kwargs):
    """`jax.vmap` over the leading seed axis, which the mesh's "seed" devices split."""
    return jax.vmap(f, spmd_axis_name=SEED, **kwargs)


def by_seed(mesh: Mesh) -> NamedSharding:
    """Leading (seed) axis split over the mesh's seed devices, replicated over its batch devices."""
    return NamedSharding(mesh, P(SEED))


def replicated(mesh: Mesh) -> NamedSharding:
    return NamedSharding(mesh, P())


def put(tree, to: NamedSharding):
    """`jax.device_put(tree, to)` of host values (or arrays on this process's devices), also where
    `to` spans other processes' devices: every process then holds the same values and hands its own
    devices their shards (`jax.make_array_from_callback`), instead of `jax.device_put`'s check
    that the processes' values agree, which gathers every array onto every process."""
    if to.is_fully_addressable:
        return jax.device_put(tree, to)

    def one(a):
        if isinstance(a, jax.Array) and not a.is_fully_addressable:  # on the global mesh already
            return jax.device_put(a, to)
        host = np.asarray(a)
        return jax.make_array_from_callback(host.shape, to, lambda index: host[index])

    return jax.tree.map(one, tree)


def split_samples(tree, mesh: Mesh | None, axis: int = 0):
    """Constrain `axis` (the samples of a minibatch) of every leaf to the mesh's batch devices.

    For use inside a function vmapped with `spmd_axis_name=SEED`; leaves whose sample count the
    batch devices do not divide, and meshes with one batch device, are left alone."""
    if mesh is None or mesh.shape[BATCH] == 1:
        return tree

    def constrain(a):
        if a.shape[axis] % mesh.shape[BATCH]:
            return a
        return jax.lax.with_sharding_constraint(a, NamedSharding(mesh, P(*[None] * axis, BATCH)))

    return jax.tree.map(constrain, tree)
