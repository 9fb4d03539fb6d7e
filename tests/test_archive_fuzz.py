"""Seeded mutations of small archives through `archive.read_archive`: every outcome is a clean
`ArchiveError` or a declared, correct reading (the original trial, or a meta whose changed field
still has its type and range). Any other exception, a read over its time or memory bound, or a
wrong reading accepted fails the test, naming the mutation."""

import io
import json
import signal
import tracemalloc
import zipfile

import numpy as np
import pytest

from fabricjax.store import archive
from tests.helpers import npz_fields, tiny_archive

N_STEPS = 8
SECONDS = 5  # per read: a tiny archive reads in milliseconds
PEAK_BYTES = 64 << 20  # per read: a tiny archive needs well under 1 MB
HOSTILE = [
    -5,
    "x",
    None,
    True,
    False,
    1.5,
    0,
    10**30,
    float("inf"),
    float("nan"),
    [],
    {},
    [1],
    "",
    2**70,
    3,
    {"a": [1]},
    ["x", "y", "z"],
]
# meta fields the reader validates (free-form dicts: source, import, force_proxy, are not mutated)
FIELDS = [
    "format_version",
    "fabric_id",
    "label",
    "properties.stretchiness",
    "properties.roughness",
    "trial",
    "condition",
    "complete",
    "day",
    "closing_steps",
    "split",
    "label_name",
    "label_map",
    "streams.mics.0.rate",
    "streams.mics.0.role",
    "streams.mics.1.name",
    "streams.joints.names",
    "streams.joints.fields",
    "streams.camera.image_size",
    "streams.camera.image_size.0",
    "streams.steps.rate",
    "streams.steps.clock",
    "streams.force",
]
COUNTS = {"fabric_id", "label", "trial", "closing_steps", "properties.stretchiness", "properties.roughness", "day"}
NULLABLE = {
    "day",
    "condition",
    "properties.stretchiness",
    "properties.roughness",
    "split",
    "streams.mics.0.role",
    "streams.force",
}
ENUMS = {
    "condition": archive.CONDITIONS,
    "split": archive.SPLITS,
    "streams.mics.0.role": archive.MIC_ROLES,
    "streams.steps.clock": archive.STEP_CLOCKS,
}


class Hang(Exception):
    pass


def _alarm(signum, frame):
    raise Hang()


def _bytes(a: archive.TrialArchive, compressed: bool = False, **changes) -> bytes:
    buf = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(buf, **npz_fields(a, **changes))
    return buf.getvalue()


def _set(meta: dict, key: str, value):
    *parents, last = key.split(".")
    node = meta
    for p in parents:
        node = node[int(p)] if isinstance(node, list) else node[p]
    if isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value


def _meta_sound(key: str, value, read: archive.TrialArchive, base: archive.TrialArchive) -> bool:
    """Whether an accepted meta whose field `key` became `value` is a correct reading of it."""
    if isinstance(value, float) and not np.isfinite(value):
        return False
    if value is None:
        return key in NULLABLE
    if key in ENUMS:
        return value in ENUMS[key] or (key == "split" and value is None)
    if key in COUNTS:
        ok = type(value) is int and 0 <= value <= archive.MAX_INT
        return ok and (key != "closing_steps" or value < read.n_steps)
    if key == "format_version":
        return value == archive.FORMAT_VERSION and type(value) is int
    if key == "complete":
        return type(value) is bool
    if key == "streams.mics.0.rate":
        return type(value) is int and 0 < value <= archive.MAX_RATE
    if key == "streams.steps.rate":
        return type(value) in (int, float) and 0 < value <= archive.MAX_RATE
    if key.startswith("streams.camera.image_size"):
        return archive.layout(read.meta).image_size == base.images.shape[1:3]
    if key in ("streams.joints.names", "streams.joints.fields"):
        return (
            isinstance(value, list)
            and all(isinstance(x, str) for x in value)
            and len(value) == len(_get(base.meta, key))
        )
    if key == "label_map":
        return isinstance(value, dict) and read.meta["label"] in value.values()
    if key in ("label_name", "streams.mics.1.name", "streams.force"):
        return isinstance(value, str)
    return False


def _get(meta, key):
    node = meta
    for p in key.split("."):
        node = node[int(p)] if isinstance(node, list) else node[p]
    return node


def _zip_bomb(a: archive.TrialArchive) -> bytes:
    """A deflated audio member of 80 MB of zeros (a 1000-fold inflation) in an otherwise valid archive."""
    n = (80 << 20) // 8
    audio = np.zeros((2, n), np.int32)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for k, v in npz_fields(a, audio=audio).items():
            member = io.BytesIO()
            np.lib.format.write_array(member, np.asarray(v), allow_pickle=False)
            z.writestr(f"{k}.npy", member.getvalue())
    return buf.getvalue()


def _header_declaring(a: archive.TrialArchive, shape) -> bytes:
    """The archive with the audio member's npy header declaring `shape` (its data left as it was)."""
    raw = _bytes(a)
    src = zipfile.ZipFile(io.BytesIO(raw))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for info in src.infolist():
            data = src.read(info)
            if info.filename == "audio.npy":
                header = io.BytesIO()
                np.lib.format.write_array_header_1_0(header, {"descr": "<i4", "fortran_order": False, "shape": shape})
                data = header.getvalue() + data[len(header.getvalue()) :]
            z.writestr(info.filename, data)
    return buf.getvalue()


def _sizes_declaring(raw: bytes, member: str, size: int) -> bytes:
    """The archive with `member`'s compressed and inflated sizes in the central directory set to `size`."""
    data, at = bytearray(raw), 0
    while (at := data.find(b"PK\x01\x02", at)) >= 0:
        name_len = int.from_bytes(data[at + 28 : at + 30], "little")
        if data[at + 46 : at + 46 + name_len] == member.encode():
            data[at + 20 : at + 28] = size.to_bytes(4, "little") * 2
        at += 4
    return bytes(data)


def _member_offsets(raw: bytes) -> dict[str, tuple[int, int]]:
    """(start of data, data length) of each stored member in the file."""
    out = {}
    with zipfile.ZipFile(io.BytesIO(raw)) as z:
        for info in z.infolist():
            name_len, extra_len = np.frombuffer(raw[info.header_offset + 26 : info.header_offset + 30], "<u2")
            start = info.header_offset + 30 + int(name_len) + int(extra_len)
            out[info.filename] = (start, info.compress_size)
    return out


def mutations(seed: int = 0):
    """(name, bytes, kind, detail) of every mutation: kind "bytes" (correct only as the original),
    "meta" (correct when the changed field is sound) or "refuse" (must be an ArchiveError)."""
    rng = np.random.default_rng(seed)
    base = tiny_archive(n_steps=N_STEPS, images=(4, 5))
    raw = _bytes(base)
    offsets = _member_offsets(raw)
    for k in range(150):  # bit flips anywhere
        data = bytearray(raw)
        pos = int(rng.integers(len(data)))
        data[pos] ^= 1 << int(rng.integers(8))
        yield f"bit flip at byte {pos}", bytes(data), "bytes", None
    for member, (start, _) in offsets.items():  # bit flips in each npy header
        for k in range(4):
            data = bytearray(raw)
            pos = start + int(rng.integers(10, 118))
            data[pos] ^= 1 << int(rng.integers(8))
            yield f"bit flip in the npy header of {member} at byte {pos}", bytes(data), "bytes", None
    for k in range(20):  # truncations
        cut = int(rng.integers(len(raw) - 1))
        yield f"truncated to {cut} bytes", raw[:cut], "refuse", None
    for k in range(140):  # hostile values of validated meta fields
        key = FIELDS[int(rng.integers(len(FIELDS)))]
        value = HOSTILE[int(rng.integers(len(HOSTILE)))]
        meta = json.loads(json.dumps(base.meta))
        _set(meta, key, value)
        yield f"meta.{key} = {value!r}", _bytes(base, meta=np.array(json.dumps(meta))), "meta", (key, value)
    start, length = offsets["audio.npy"]
    changed = bytearray(raw)
    changed[start + length - 2] ^= 0x10  # an audio word changed: only the CRC tells
    yield "an audio word changed", bytes(changed), "refuse", None
    meta = json.dumps(base.meta)
    for name, text in [
        ("meta nested 100,000 deep", meta[:-1] + ', "x": ' + "[" * 100_000 + "]" * 100_000 + "}"),
        ("a meta integer of 5,000 digits", meta.replace('"trial": 0', '"trial": ' + "9" * 5000)),
        ("meta of 6 MB", meta[:-1] + ', "x": "' + "a" * (6 << 20) + '"}'),
        ("meta steps.rate Infinity", meta.replace('"rate": 50}', '"rate": Infinity}')),
        ("meta not JSON", meta[:-3]),
        ("meta a JSON list", "[1, 2]"),
    ]:
        yield name, _bytes(base, meta=np.array(text)), "refuse", None
    yield "meta an int array", _bytes(base, meta=np.arange(3)), "refuse", None
    for name, shape in [
        ("an npy header declaring terabytes", (2, 1 << 40)),
        ("an npy header of another shape", (2, 7)),
    ]:
        yield name, _header_declaring(base, shape), "refuse", None
    yield "a stored member declaring 4 GB", _sizes_declaring(raw, "timestamps.npy", 0xFFFFFFF0), "refuse", None
    npy = io.BytesIO()
    np.save(npy, base.audio)
    yield "a plain .npy renamed .npz", npy.getvalue(), "refuse", None
    nomagic = io.BytesIO()
    with zipfile.ZipFile(nomagic, "w") as z:
        for k, v in npz_fields(base).items():
            z.writestr(
                f"{k}.npy",
                b"no magic here"
                if k == "joints"
                else (lambda b: (np.lib.format.write_array(b, np.asarray(v)), b.getvalue())[1])(io.BytesIO()),
            )
    yield "a member without the npy magic", nomagic.getvalue(), "refuse", None
    yield "a zip bomb (deflated member 1000-fold)", _zip_bomb(base), "refuse", None
    yield "a compressed archive", _bytes(base, compressed=True), "bytes", None
    yield "object dtype", _bytes(base, force=np.array([None] * N_STEPS, object)), "refuse", None


def _read(path):
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(SECONDS)
    tracemalloc.start()
    try:
        return archive.read_archive(path)
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
        if peak > PEAK_BYTES:
            raise MemoryError(f"peak {peak} bytes")


def _same(a: archive.TrialArchive, b: archive.TrialArchive) -> bool:
    return (
        a.meta == b.meta
        and all(
            np.array_equal(getattr(a, k), getattr(b, k)) and getattr(a, k).dtype == getattr(b, k).dtype
            for k in a.arrays()
        )
        and set(a.arrays()) == set(b.arrays())
    )


def test_every_mutation_is_a_clean_error_or_a_correct_reading(tmp_path):
    base = tiny_archive(n_steps=N_STEPS, images=(4, 5))
    path = tmp_path / "trial.npz"
    outcomes, failures = {"error": 0, "read": 0}, []
    for n, (name, data, kind, detail) in enumerate(mutations()):
        path.write_bytes(data)
        try:
            read = _read(path)
        except archive.ArchiveError as e:
            outcomes["error"] += 1
            if str(path) not in str(e) or "\n" in str(e):
                failures.append(f"{name}: error not one line naming the file: {e}")
            continue
        except Exception as e:  # noqa: BLE001 - the test's point: any other exception is a failure
            failures.append(f"{name}: {type(e).__name__}: {e}"[:300])
            continue
        outcomes["read"] += 1
        if kind == "refuse":
            failures.append(f"{name}: accepted")
        elif kind == "bytes" and not _same(read, base):
            failures.append(f"{name}: accepted a reading that differs from the original")
        elif kind == "meta" and not _meta_sound(*detail, read, base):
            failures.append(f"{name}: accepted")
    assert not failures, "\n".join(failures)
    assert n + 1 >= 300 and outcomes["error"] > 200 and outcomes["read"] >= 5, outcomes  # both outcomes exercised


@pytest.mark.parametrize(
    "key, value",
    [
        ("closing_steps", -5),
        ("closing_steps", N_STEPS),
        ("day", False),
        ("properties.roughness", True),
        ("streams.steps.rate", True),
        ("label", -1),
        ("streams.mics.0.rate", 48000.5),
        ("label_map", {"a": [1]}),
        ("streams.joints", "angle"),
        ("streams.camera.image_size", ["x", None]),
    ],
)
def test_each_accepted_wrong_case_of_the_report_is_refused(tmp_path, key, value):
    base = tiny_archive(n_steps=N_STEPS, images=(4, 5))
    meta = json.loads(json.dumps(base.meta))
    _set(meta, key, value)
    path = tmp_path / "t.npz"
    path.write_bytes(_bytes(base, meta=np.array(json.dumps(meta))))
    field = key.replace(".0.", "[0].").replace(".", r"\.").replace("[", r"\[").replace("]", r"\]")
    with pytest.raises(archive.ArchiveError, match=rf"t\.npz: field 'meta\.{field}'"):
        archive.read_archive(path)


def test_a_valid_archive_reads_as_numpy_reads_it(tmp_path):
    base = tiny_archive(n_steps=N_STEPS, images=(4, 5))
    for compressed in (False, True):
        path = tmp_path / f"t{compressed}.npz"
        path.write_bytes(_bytes(base, compressed=compressed))
        read = archive.read_archive(path)
        with np.load(path, allow_pickle=False) as z:
            for k, v in read.arrays().items():
                np.testing.assert_array_equal(v, z[k])
                assert v.dtype == z[k].dtype and v.flags.writeable
        assert _same(read, base)
