"""Data parallelism over minibatch samples: one code path for one CPU, one GPU or many devices.

The training mesh has one axis, "batch": every minibatch's samples are split over its devices and
XLA sums each step's gradients over them with an all-reduce, so results equal a one-device run up
to the order of float summation. Seeds are a `jax.vmap`ped leading axis of every training array
and stay together on every device: the layout depends on the batch size and the devices, never on
the seed count, so a seed's result does not depend on how many seeds train beside it.

A CPU is one device by default; `runtime.use_cpu_cores` makes it one device per core (the
training and benchmark commands call it first, through `runtime.configure_jax`), so that samples
run on separate cores instead of sharing each op. A single prediction answers faster on a
one-device CPU, whose ops use every core, so latency-bound commands keep one device.

In a run over several processes (`runtime.join_processes`) `jax.devices()` lists every process's
devices, so the mesh spans them all: host values go onto it with `put`, and what training returns
is replicated on every device, so every process reads it whole with `jax.device_get`.
"""

from __future__ import annotations

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

BATCH = "batch"


def training_mesh(batch_size: int = 1) -> Mesh:
    """The ("batch",) mesh: every minibatch's samples are split over the largest device count that
    divides `batch_size`."""
    devices = jax.devices()
    batch = max(d for d in range(1, len(devices) + 1) if batch_size % d == 0)
    return Mesh(np.asarray(devices[:batch]), (BATCH,))


def vmap_seeds(f, **kwargs):
    """`jax.vmap` over the leading seed axis; the seeds stay together on every device."""
    return jax.vmap(f, **kwargs)


def replicated(mesh: Mesh) -> NamedSharding:
    """Every device of `mesh` holds the whole array: the data sets and the per-seed training state."""
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

    Leaves whose sample count the batch devices do not divide, and meshes with one batch device,
    are left alone."""
    if mesh is None or mesh.shape[BATCH] == 1:
        return tree

    def constrain(a):
        if a.shape[axis] % mesh.shape[BATCH]:
            return a
        return jax.lax.with_sharding_constraint(a, NamedSharding(mesh, P(*[None] * axis, BATCH)))

    return jax.tree.map(constrain, tree)
