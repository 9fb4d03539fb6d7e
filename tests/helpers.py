"""Small builders shared by tests (not fixtures: plain functions tests call explicitly)."""

import json
import zlib
from typing import Any

import numpy as np

from fabricjax import catalog
from fabricjax.store import archive


def tiny_archive(n_steps=30, fabric_id=4, day=1, trial=0, condition="lab", images=(12, 16), seed=0, reference=True):
    """A valid trial archive of random streams; with frames, its session's no-contact reference
    (one frame, the same for every trial of the day and condition) unless `reference` is False."""
    rng = np.random.default_rng(seed)
    with_reference = images is not None and reference
    session = f"day{day}_{condition}"
    hop = archive.AUDIO_RATE // archive.STEP_RATE  # 960 samples per step
    n_samples = archive.WINDOW + hop * n_steps
    window_end = np.stack([archive.WINDOW + hop * np.arange(n_steps)] * 2, axis=1).astype(np.int64)
    meta = archive.make_meta(
        fabric_id=fabric_id,
        properties=catalog.fabric(fabric_id).properties,
        day=day,
        trial=trial,
        condition=condition,
        source={"kind": "test"},
        image_size=images,
        **({"reference": {"how": "test: random", "session": session, "times_s": [-1.0]}} if with_reference else {}),
    )
    return archive.TrialArchive(
        meta=meta,
        timestamps=np.arange(n_steps) * 0.02,
        window_end=window_end,
        joints=rng.normal(size=(n_steps, 6, 3)).astype(np.float32),
        force=np.full(n_steps, 0.1, np.float32),
        audio=(rng.integers(-(2**17), 2**17, size=(2, n_samples)) << 14).astype(np.int32),
        images=None if images is None else rng.integers(0, 255, size=(n_steps, *images, 3), dtype=np.uint8),
        reference=np.random.default_rng(zlib.crc32(session.encode())).integers(
            0, 255, size=(1, *images, 3), dtype=np.uint8
        )
        if with_reference
        else None,
    )


def tiny_dataset(folder, trials, n_steps=45, images=(12, 16), seed=0):
    """Write one tiny archive per (fabric_id, day, trial, condition) into `folder`; `n_steps` may
    be a dict from that tuple to a step count; `seed` draws another dataset. Returns the folder."""
    for i, (fabric_id, day, trial, condition) in enumerate(trials):
        n = n_steps.get((fabric_id, day, trial, condition), 45) if isinstance(n_steps, dict) else n_steps
        a = tiny_archive(
            n, fabric_id=fabric_id, day=day, trial=trial, condition=condition, images=images, seed=seed + i
        )
        archive.write_archive(f"{folder}/{archive.trial_filename(a.meta)}", a)
    return folder


def npz_fields(base, **changes):
    """The npz fields of archive `base` with some replaced (None deletes): bypasses validation."""
    fields = {"meta": np.array(json.dumps(base.meta)), **base.arrays()}
    for k, v in changes.items():
        if v is None:
            fields.pop(k)
        else:
            fields[k] = v
    return fields


def read_rrd(path) -> dict[str, dict[str, Any]]:
    """{entity path: {"rows": rows logged, "steps": sorted distinct "step" values}} of a .rrd file
    (static data left out; the waveforms are on "time" only, so their "steps" are [])."""
    from rerun.chunk import RrdReader

    out: dict[str, dict[str, Any]] = {}
    for chunk in RrdReader(str(path)).stream():
        if chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        entry = out.setdefault(chunk.entity_path, {"rows": 0, "steps": set()})
        entry["rows"] += chunk.num_rows
        if "step" in batch.schema.names:
            entry["steps"].update(batch.column("step").to_pylist())
    return {k: {**v, "steps": sorted(v["steps"])} for k, v in out.items()}


def reference_rotate(frames, degrees):
    """The rotation augmentation as the model applied it before it moved to pixel rows
    (`features.images.rotate_rows`), kept verbatim as the reference the rows must equal: rotate
    (N, H, W, C) frames by `degrees` about the centre with bilinear interpolation, 0 outside."""
    import jax.numpy as jnp

    n, h, w, c = frames.shape
    theta = jnp.deg2rad(degrees)
    cy, cx = (h - 1) / 2.0, (w - 1) / 2.0
    yy, xx = jnp.meshgrid(jnp.arange(h, dtype=jnp.float32) - cy, jnp.arange(w, dtype=jnp.float32) - cx, indexing="ij")
    cos, sin = jnp.cos(theta), jnp.sin(theta)
    sy = cos * yy - sin * xx + cy
    sx = sin * yy + cos * xx + cx
    y0, x0 = jnp.floor(sy), jnp.floor(sx)
    fy, fx = sy - y0, sx - x0
    x = frames.astype(jnp.float32)
    out = jnp.zeros((n, h, w, c), jnp.float32)
    for dy, dx, weight in ((0, 0, (1 - fy) * (1 - fx)), (0, 1, (1 - fy) * fx), (1, 0, fy * (1 - fx)), (1, 1, fy * fx)):
        yi, xi = (y0 + dy).astype(jnp.int32), (x0 + dx).astype(jnp.int32)
        inside = (yi >= 0) & (yi < h) & (xi >= 0) & (xi < w)
        pixels = x[:, jnp.clip(yi, 0, h - 1), jnp.clip(xi, 0, w - 1)]
        out = out + jnp.where(inside, weight, 0.0)[None, :, :, None] * pixels
    return out


def reference_rotate_batch(key, frames, max_degrees=90.0):
    """(B, N, H, W, C): an independent angle per sequence from `key`, as the model drew them."""
    import jax

    keys = jax.random.split(key, frames.shape[0])
    angles = jax.vmap(lambda k: jax.random.uniform(k, (), minval=-max_degrees, maxval=max_degrees))(keys)
    return jax.vmap(reference_rotate)(frames, angles)


class CountingCamera:
    """Frames 0, 1, 2, ... (each filled with its index), the way `Camera.read` delivers them; starts
    with `dropped` frames already counted."""

    def __init__(self, dropped: int = 0):
        self.count, self.dropped = 0, dropped

    def read(self):
        self.count += 1
        return np.full((4, 6, 3), self.count - 1, np.uint8)
