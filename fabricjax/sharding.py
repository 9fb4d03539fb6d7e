"""Seed-axis data parallelism: one code path for one CPU, one GPU or many devices.

Every training array carries a leading seed axis (`jax.vmap` over seeds), so splitting that axis
over a 1-D mesh runs independent seeds on different devices with no communication; the data is
replicated. With one device the mesh is trivial and nothing changes.
"""

from __future__ import annotations

import jax
from jax.sharding import Mesh, NamedSharding, PartitionSpec as P

AXIS = "seed"


def seed_mesh(n_seeds: int) -> Mesh:
    """A mesh over the most devices that divide `n_seeds` evenly (every device gets equal work)."""
    devices = jax.devices()
    n = max(d for d in range(1, len(devices) + 1) if n_seeds % d == 0)
    return Mesh(devices[:n], (AXIS,))


def by_seed(mesh: Mesh) -> NamedSharding:
    """Leading axis split over the mesh."""
    return NamedSharding(mesh, P(AXIS))


def replicated(mesh: Mesh) -> NamedSharding:
    return NamedSharding(mesh, P())
