"""The flags the import commands share, defined once: where archives go (`--out`), the trial's
fields (`--fabric`, `--day`, `--trial`, `--condition`, `--session`: `define_trial`, read back by
`trial_overrides`), the camera's session reference (`--reference`, `--reference_frames`), and
`--resample`, `--overwrite` and `--map`. Each command says what its flags act on in its own words
(one archive or a folder of them, a bag's mapping or the command line), so the help reads right
for each; the names, types and defaults are these.
"""

from __future__ import annotations

from typing import Any

from absl import flags

from fabricjax.store import archive


def define_out(what: str) -> None:
    """--out: the folder `what` (one trial archive, the trial archives) is written into."""
    flags.DEFINE_string("out", None, f"Folder to write {what} into.", required=True)


def define_map(help: str, required: bool = False) -> None:
    """--map: a mapping file (TOML) of ROS 2 bags (`fabricjax.importers.mapping_file`)."""
    flags.DEFINE_string("map", None, help, required=required)


def define_trial(overrides: bool, condition: str | None = None) -> None:
    """--fabric, --day, --trial, --condition (default `condition`) and --session; `overrides`: they
    override a mapping's [trial] table, whose field each names."""

    def over(field: str) -> str:
        return f" (overrides {field})" if overrides else ""

    fabric = over("the mapping's trial.fabric_id")
    flags.DEFINE_integer("fabric", None, f"Fabric id{fabric}.")
    flags.DEFINE_integer("day", None, f"Recording day{over('trial.day')}.")
    flags.DEFINE_integer("trial", None, f"Trial index{over('trial.trial')}.")
    flags.DEFINE_enum("condition", condition, list(archive.CONDITIONS), f"Acoustic condition{over('trial.condition')}.")
    flags.DEFINE_string(
        "session",
        None,
        "Session whose camera reference the trial shares ("
        + ("overrides trial.session; " if overrides else "")
        + "default: day and condition).",
    )


def trial_overrides(values: flags.FlagValues) -> dict[str, Any]:
    """The trial fields the flags of `define_trial` give (None: not given), as
    `mapping_file.trial_fields` takes them."""
    return {
        "fabric_id": values.fabric,
        "day": values.day,
        "trial": values.trial,
        "condition": values.condition,
        "session": values.session,
    }


def define_reference(help: str, trials: str) -> None:
    """--reference (`help`) and --reference_frames: with --reference=pre_contact, how many of
    `trials` (the trial's, each trial's) first frames make the camera's session reference."""
    flags.DEFINE_string("reference", None, help)
    flags.DEFINE_integer(
        "reference_frames", None, f"With --reference=pre_contact: how many of {trials} first frames (default 5)."
    )


def define_resample(what: str) -> None:
    """--resample: `what` (the microphones, the WAV files) not at 48 kHz are resampled."""
    flags.DEFINE_bool(
        "resample", False, f"Resample {what} not at 48 kHz (scipy.signal.resample_poly; recorded in the meta)."
    )


def define_overwrite(help: str) -> None:
    """--overwrite: what an import may replace in --out (`help`); default False, replace nothing."""
    flags.DEFINE_bool("overwrite", False, help)
