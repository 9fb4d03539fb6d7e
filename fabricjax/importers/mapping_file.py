"""The TOML files that say what a recording holds (`read_toml`), the bag mapping that names its
topics and its camera's session reference (`load_mapping`; format in docs/data.md, "From ROS 2
bags", the reference keys in `fabricjax.importers.ros_bag`), and a trial's fabric, day, trial,
condition and optional session from a mapping's [trial] table and the command line
(`trial_fields`)."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from fabricjax.importers import ros_bag
from fabricjax.importers.streams import RecordingImportError
from fabricjax.store import archive

TRIAL_KEYS = ("fabric_id", "day", "trial", "condition")


def read_toml(path: Path, what: str) -> dict[str, Any]:
    """A TOML file (`what`: "mapping", "rig", ...) as a dict; a missing or malformed file is a
    one-line error naming it."""
    try:
        return tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise RecordingImportError(path, "<file>", f"no such {what} file") from None
    except tomllib.TOMLDecodeError as e:
        raise RecordingImportError(path, "<file>", f"not valid TOML: {e}") from None


def load_mapping(path: str | Path) -> dict[str, Any]:
    """The mapping file, checked for the keys `import_bag` needs (a camera's reference among them),
    before any bag is read or archive written."""
    path = Path(path)
    mapping = read_toml(path, "mapping")
    for key in ("camera.topic", "joints.topic", *(f"mics.{m}.topic" for m in archive.MIC_NAMES)):
        node: Any = mapping
        for part in key.split("."):
            if not isinstance(node, dict) or part not in node:
                raise RecordingImportError(path, key, "missing")
            node = node[part]
    ros_bag.check_mapping(mapping, path)
    return mapping


def trial_fields(mapping: dict[str, Any], overrides: dict[str, Any], where) -> dict[str, Any]:
    """fabric_id, day, trial, condition and optionally session (the name trials that share a camera
    reference share, meta.reference.session): the command line wins over the mapping's [trial] table."""
    trial = dict(mapping.get("trial", {})) | {k: v for k, v in overrides.items() if v is not None}
    for key in TRIAL_KEYS:
        if key not in trial:
            raise RecordingImportError(
                where, f"trial.{key}", "missing (give it in the mapping's [trial] table or on the command line)"
            )
    if trial["condition"] not in archive.CONDITIONS:
        raise RecordingImportError(
            where, "trial.condition", f"must be one of {archive.CONDITIONS}, got {trial['condition']!r}"
        )
    if "session" in trial and (not isinstance(trial["session"], str) or not trial["session"].strip()):
        raise RecordingImportError(where, "trial.session", f"must be a session's name, got {trial['session']!r}")
    return trial
