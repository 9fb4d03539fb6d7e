"""One writer at a time for what runs share in a workspace: a dataset, the feature cache, a
study's checkpoints, an import's output folder.

A writer holds an exclusive lock, readers a shared one (`hold`); a run that finds what it needs
held the other way ends in one line naming the other run's PID and command (`Busy`), before it
has written anything. The locks are `flock`s on files under `<workspace>/locks/` (an import's in
its output folder): the kernel releases them when their process ends, however it ends (kill -9
included), so a lock is never stale; each holder also leaves a note (its PID, command and what it
is doing) beside the lock for the refusal to name, and a note whose PID is gone is removed.

Locks are re-entrant within a process: a run that reads a dataset (shared) and then simulates its
missing trials (exclusive) upgrades its own lock, which fails only while another run reads it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import fcntl
import hashlib
import json
import os
import sys
from pathlib import Path
from typing import Iterator

from fabricjax.errors import UserError
from fabricjax.store import provenance, workspace

LOCKS = "locks"


class Busy(UserError):
    """What a run needs is held by another run."""


@dataclasses.dataclass
class _Held:
    fd: int
    shared: bool


_HELD: dict[Path, _Held] = {}  # this process's locks, by lock file


def lock_file(thing: str | os.PathLike, workdir=None) -> Path:
    """The lock of `thing` (a path a run writes or reads) in the workspace's lock folder."""
    resolved = Path(thing).expanduser().resolve()
    return (
        workspace.root(workdir)
        / LOCKS
        / f"{resolved.name}-{hashlib.sha256(str(resolved).encode()).hexdigest()[:12]}.lock"
    )


@contextlib.contextmanager
def hold(
    lock: Path, what: str, doing: str, *, shared: bool = False, wait: bool = False, transient: bool = False
) -> Iterator[None]:
    """Hold `lock` (`lock_file`) for `what` (its name in messages) while the block runs: shared
    (reading) or exclusive (writing, `doing` says what); `Busy` if another run holds it the other
    way, or with `wait` (for locks held briefly) a line saying whom this run waits for, then the
    wait. `transient` (an exclusive lock in a folder people read, such as an import's output):
    the lock file is removed at the end, while still held, so no second holder can slip in."""
    lock = Path(lock)
    held = _HELD.get(lock)
    if held is not None and (shared or not held.shared):  # held already, at least as strongly
        yield
        return
    if held is not None:  # this process reads it and now writes it: upgrade, then back to shared
        _flock(held.fd, lock, what, fcntl.LOCK_EX)
        held.shared = False
        _note(lock, doing, shared=False)
        try:
            yield
        finally:
            fcntl.flock(held.fd, fcntl.LOCK_SH)
            held.shared = True
            _note(lock, doing, shared=True)
        return
    lock.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        _flock(fd, lock, what, fcntl.LOCK_SH if shared else fcntl.LOCK_EX, wait)
    except BaseException:
        os.close(fd)
        raise
    _HELD[lock] = _Held(fd, shared)
    _others(lock)  # removes the notes a killed holder left
    _note(lock, doing, shared)
    try:
        yield
    finally:
        del _HELD[lock]
        _note_path(lock).unlink(missing_ok=True)
        if transient and not shared:
            lock.unlink(missing_ok=True)
        os.close(fd)  # releases the flock


def _flock(fd: int, lock: Path, what: str, mode: int, wait: bool = False) -> None:
    try:
        fcntl.flock(fd, mode | fcntl.LOCK_NB)
    except BlockingIOError:
        if not wait:
            raise Busy(
                f"{what} is in use by {_holder(lock)}; wait for it to end, or give this run another --workdir"
            ) from None
        print(f"waiting: {what} is in use by {_holder(lock)}", file=sys.stderr, flush=True)
        fcntl.flock(fd, mode)


def _note_path(lock: Path, pid: int | None = None) -> Path:
    return lock.with_name(f"{lock.name}.{os.getpid() if pid is None else pid}")


def _note(lock: Path, doing: str, shared: bool) -> None:
    """Say who holds `lock` for a refusal to name; the lock holds without it (a full disk)."""
    note = {"pid": os.getpid(), "command": provenance.command_line(), "doing": doing, "shared": shared}
    try:
        _note_path(lock).write_text(json.dumps(note))
    except OSError:
        _note_path(lock).unlink(missing_ok=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def _others(lock: Path) -> list[dict]:
    """The notes of the other live runs holding `lock`; notes of ended processes are removed."""
    notes = []
    for path in lock.parent.glob(f"{lock.name}.*"):
        try:
            note = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if note.get("pid") == os.getpid():
            continue
        if not _alive(int(note.get("pid", 0))):
            path.unlink(missing_ok=True)
            continue
        notes.append(note)
    return notes


def _holder(lock: Path) -> str:
    """The other runs holding `lock`, in words (a writer first)."""
    notes = _others(lock)
    if not notes:
        return "another run (it has not said which yet)"
    notes.sort(key=lambda n: n.get("shared", True))
    n = notes[0]
    more = f" and {len(notes) - 1} other runs" if len(notes) > 1 else ""
    return f"PID {n['pid']} ({n['command']}: {n['doing']}){more}"
