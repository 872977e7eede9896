"""What every command shares: the command record, argument types and the shared options.

A :class:`Command` is one row of the command table: its name, handler, help
with an example, and a function that adds its options. The model's commands
are listed by area in this package; other installed packages add rows through
the ``livox_viz.commands`` entry-point group (see :func:`livox_viz.cli.main`).
"""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from livox_viz.config.presets import DEFAULT_PRESET, load_preset
from livox_viz.config.returns_params import RETURN_MODELS
from livox_viz.config.sensor import SDKS, SensorConfig, load_config
from livox_viz.core.atomic import resolve_destination, write_text_atomic
from livox_viz.core.errors import LivoxVizError, quoted
from livox_viz.core.jsonfile import dumps_readable
from livox_viz.core.poses import Pose
from livox_viz.core.workload import TriangleBudget
from livox_viz.scene.materials import DEFAULT_REFLECTANCE

PROG = "livox-viz"
Handler = Callable[[argparse.Namespace], int]


class UsageError(LivoxVizError):
    """A command-line value that does not parse or is not allowed."""


@dataclass(frozen=True)
class Command:
    """One subcommand of ``livox-viz``.

    Parameters
    ----------
    name : str
    handler : callable
        Runs the command with the parsed arguments; returns the exit status.
    help : str
        One line.
    example : str
        A command line shown in ``--help``.
    arguments : callable
        Adds the command's options to its parser.
    default : bool
        Run this command when none is named (at most one command may say so).
    """

    name: str
    handler: Handler
    help: str
    example: str
    arguments: Callable[[argparse.ArgumentParser], None]
    default: bool = False


# Argument types -------------------------------------------------------------------------
def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{quoted(text)} is not a number") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"{quoted(text)}: allowed: a finite number > 0")
    return value


def float_list(text: str) -> list[float]:
    """argparse type: comma-separated numbers > 0, e.g. ``0.1,0.5,1``."""
    values = [positive_float(part) for part in text.split(",") if part.strip()]
    if not values:
        raise argparse.ArgumentTypeError(f"{quoted(text)}: allowed: numbers > 0 separated by commas")
    return values


def whole_number(low: int, high: int, meaning: str = "") -> Callable[[str], int]:
    """argparse type: a whole number in [low, high]; ``meaning`` says what the ends mean."""

    def parse(text: str) -> int:
        # int() also takes "+5", "1_000", " 5 " and other scripts' digits ("٣"): "--port 1_000" listened on 1000.
        if not (text.isascii() and text.removeprefix("-").isdigit()):
            raise argparse.ArgumentTypeError(f"{quoted(text)} is not a whole number (digits 0-9)")
        value = int(text)
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{text}: allowed: {meaning or f'{low} to {high}'}")
        return value

    return parse


def reflectance_value(text: str) -> float:
    """argparse type: a Lambertian reflectance in [0, 1]."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{quoted(text)} is not a number") from None
    if not math.isfinite(value) or not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"{quoted(text)}: allowed: a reflectance from 0 to 1")
    return value


seed_value = whole_number(0, 2**63 - 1, "a whole number from 0 to 2**63 - 1")
port_value = whole_number(0, 65535, "0 (any free port) to 65535")


# Shared options -------------------------------------------------------------------------
def add_config_arguments(parser: argparse.ArgumentParser) -> None:
    """``--preset NAME | --config FILE [--seq-id N] [--returns ideal|datasheet]``."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--preset", help=f"preset name or JSON path (default {DEFAULT_PRESET})")
    group.add_argument("--config", help="RflySim sensor JSON or Config.json")
    parser.add_argument("--seq-id", type=int, help="SeqID of the sensor to use in a Config.json")
    parser.add_argument("--returns", choices=RETURN_MODELS,
                        help="what a ray returns: ideal (its exact first hit, as RflySim computes: no noise, no "
                             "intensity) or datasheet (the sensor's sheet: noise, detection range, beam footprint, "
                             "multiple returns, reflectivity, tags); default: the configuration's own "
                             "(LivoxVizReturns; ideal without one, and the Mid-70's sheet for datasheet)")


def add_sdk_argument(parser: argparse.ArgumentParser) -> None:
    """``--sdk v2|v3``: the RflySim SDK a written configuration is for (default: the one it was read in)."""
    parser.add_argument("--sdk", choices=SDKS,
                        help="write the configuration for RflySim SDK v2 (TypeID 6, 8 otherParams) or v3 (TypeID "
                             "22, or 23 for the Mid-360; EularOrQuat, SensorAngQuat, 16 otherParams); default: "
                             "as it was read")


def write_config_json(path: str, config: SensorConfig, sdk: str | None, extra: dict[str, str] | None = None) -> str:
    """Write ``config`` (for ``sdk``, or as read) as one RflySim sensor object to ``path``, atomically; returns
    what was written, in words (``TypeID 22, RflySim SDK v3 form``)."""
    if sdk is not None:
        config = config.with_sdk(sdk)
    write_text_atomic(path, dumps_readable({**config.to_json_dict(), **(extra or {})}))
    form = "v3 form (EularOrQuat, 16 otherParams)" if config.v3_form else "old form (8 otherParams)"
    return f"TypeID {config.type_id}, RflySim SDK {config.sdk}, {form}"


def add_seed_argument(parser: argparse.ArgumentParser) -> None:
    """``--seed N`` (the rosette's random generator; a Risley stream ignores it)."""
    parser.add_argument("--seed", type=seed_value, default=0, help="random seed, >= 0 (default 0)")


def config_from_args(args: argparse.Namespace) -> SensorConfig:
    """The configuration the ``--preset``/``--config`` arguments name."""
    if getattr(args, "config", None):
        config = load_config(args.config, seq_id=args.seq_id)
    else:
        refuse_seq_id_without_config(args)
        config = load_preset(getattr(args, "preset", None) or DEFAULT_PRESET)
    returns = getattr(args, "returns", None)
    return config.with_returns_model(returns) if returns else config


def refuse_seq_id_without_config(args: argparse.Namespace) -> None:
    """``--seq-id`` picks a sensor out of ``--config``'s Config.json: without one it was ignored (``info --seq-id 3``
    described the default preset's SeqID 0 sensor), so it is refused."""
    if getattr(args, "seq_id", None) is not None and not getattr(args, "config", None):
        raise UsageError(f"--seq-id {args.seq_id} without --config; allowed: with --config Config.json (it picks "
                         "the Livox sensor of that SeqID there)")


def config_label(args: argparse.Namespace) -> str:
    """A short name for the configuration in use (for titles and sidecars)."""
    if getattr(args, "config", None):
        return Path(args.config).stem
    preset = getattr(args, "preset", None)
    return Path(preset).stem if preset else DEFAULT_PRESET


def add_scene_arguments(parser: argparse.ArgumentParser) -> None:
    """``--scene NAME|FILE [--up z|y] [--pose x,y,z,roll,pitch,yaw]``."""
    parser.add_argument("--scene", default="urban", help="scene preset name or mesh file (default urban)")
    parser.add_argument("--up", choices=("z", "y"), default="z", help="up axis of a mesh file (default z)")
    parser.add_argument("--pose", help="vehicle pose x,y,z,roll,pitch,yaw in metres/radians, NED "
                                       "(default: the scene's own)")
    parser.add_argument("--exact", action="store_true",
                        help="recompute every range in float64 from its triangle's plane (about 10 %% slower; "
                             "the default float32 ranges are good to 1e-7 of the scene's size)")
    parser.add_argument("--reflectance", type=reflectance_value,
                        help="Lambertian reflectance 0-1 of surfaces without a material of their own (mesh files "
                             "without a sidecar or colours, scene objects without one); default "
                             f"{DEFAULT_REFLECTANCE:g}, about dry concrete at 905 nm; with datasheet returns only "
                             "(ideal points carry no reflectivity)")


def scene_reflectance(args: argparse.Namespace) -> float:
    """``--reflectance``, or the default for surfaces without a material of their own."""
    value = getattr(args, "reflectance", None)
    return DEFAULT_REFLECTANCE if value is None else value


def scene_from_args(args: argparse.Namespace, config: SensorConfig | None = None):
    """The :class:`~livox_viz.scene.scenes.Scene`, vehicle :class:`~livox_viz.core.poses.Pose` and ray caster named.

    With the ``config`` the command scans with, ``--reflectance`` is refused where its returns are ideal (its
    points carry no reflectivity: the value would be ignored); the window, which switches models, passes none.
    """
    from livox_viz.scene.raycast import EmbreeCaster
    from livox_viz.scene.scenes import open_scene

    if config is not None and getattr(args, "reflectance", None) is not None and config.returns_model == "ideal":
        raise UsageError("--reflectance with ideal returns (the configuration's own, or --returns ideal); allowed: "
                         "with --returns datasheet (ideal points carry no reflectivity, so it would change nothing)")

    # The scene's triangles are budgeted as it is read (--force lifts it where the command has --force).
    budget = TriangleBudget(force=getattr(args, "force", False), can_force=hasattr(args, "force"))
    scene = open_scene(args.scene, up=args.up, reflectance=scene_reflectance(args), triangles=budget)
    pose = Pose.parse(args.pose) if args.pose else scene.vehicle_pose
    return scene, pose, EmbreeCaster(scene.mesh, exact=getattr(args, "exact", False))


def add_trajectory_arguments(parser: argparse.ArgumentParser) -> None:
    """``--trajectory FILE|hover|line|circle|figure8 [--trajectory-speed V]``."""
    from livox_viz.motion.flights import (
        BUILTIN_TRAJECTORIES,
        CIRCLE_RADIUS,
        FIGURE8_SIZE,
        MAX_SPEED,
        RAMP_SECONDS,
        peak_yaw_rate,
    )
    from livox_viz.motion.tum import MAX_LINE_CHARS, MAX_POSES

    speed = DEFAULT_TRAJECTORY_SPEED
    parser.add_argument("--trajectory", help=f"a moving vehicle: a built-in flight ({', '.join(BUILTIN_TRAJECTORIES)}; "
                                             f"from rest to rest, {RAMP_SECONDS:g} s ramps; circle {CIRCLE_RADIUS:g} m "
                                             f"radius, figure8 {FIGURE8_SIZE:g} m long; at {speed:g} m/s they yaw at "
                                             f"most {peak_yaw_rate('circle', speed):.2f} and "
                                             f"{peak_yaw_rate('figure8', speed):.2f} rad/s, in proportion to the "
                                             "speed) or a TUM file (t x y z qx "
                                             "qy qz qw, world NED, t from the scan start; read only as far as the "
                                             f"scan needs, at most {MAX_POSES:,} poses, lines of at most "
                                             f"{MAX_LINE_CHARS} characters)")
    parser.add_argument("--trajectory-speed", type=float, default=None,
                        help=f"cruising speed of a built-in flight, 0 to {MAX_SPEED:g} m/s (default "
                             f"{DEFAULT_TRAJECTORY_SPEED:g})")


DEFAULT_TRAJECTORY_SPEED = 5.0


def trajectory_from_args(args: argparse.Namespace, start: Pose, seconds: float | None, whole_file: bool = False):
    """The :class:`~livox_viz.motion.trajectory.Trajectory` ``--trajectory`` names (None without one).

    A built-in flight starts at ``start`` (the scene's vehicle pose or ``--pose``) and lasts ``seconds``
    (at rest at both ends). A TUM file is read as far as a scan of ``seconds`` needs (all of it with
    ``whole_file`` or no ``seconds``). Options that would be ignored are refused.
    """
    from livox_viz.motion.flights import BUILTIN_TRAJECTORIES, builtin_trajectory
    from livox_viz.motion.tum import load_tum

    text = getattr(args, "trajectory", None)
    speed = getattr(args, "trajectory_speed", None)
    if not text:
        if speed is not None:
            raise UsageError("--trajectory-speed without --trajectory; allowed: with a built-in flight "
                             f"(--trajectory {'|'.join(BUILTIN_TRAJECTORIES)})")
        return None
    if text in BUILTIN_TRAJECTORIES:
        if seconds is None or not math.isfinite(seconds):
            raise UsageError("a built-in --trajectory needs a finite --seconds (it is made for the scan's length)")
        if text == "hover" and speed is not None:
            raise UsageError("--trajectory-speed with hover; allowed: with a flight that moves (line, circle, figure8)")
        return builtin_trajectory(text, DEFAULT_TRAJECTORY_SPEED if speed is None else speed, start, seconds)
    if not Path(text).exists():
        raise UsageError(f"--trajectory {quoted(text)}: no such TUM trajectory file; allowed: a TUM file or a built-in "
                         f"flight: {', '.join(BUILTIN_TRAJECTORIES)}")
    if speed is not None:
        raise UsageError("--trajectory-speed with a TUM file; allowed: with a built-in flight only (a TUM file "
                         "gives its own times)")
    if getattr(args, "pose", None):
        raise UsageError("--pose with a TUM file; allowed: with a built-in flight or no --trajectory (a TUM file's "
                         "poses are absolute, in the world NED frame)")
    stop = None if whole_file or seconds is None or not math.isfinite(seconds) else seconds
    return load_tum(text, start=None if stop is None else 0.0, stop=stop)


def check_output_path(path: str | Path, suffixes: tuple[str, ...]) -> Path:
    """Refuse an output path before any work: wrong suffix, a folder, a missing or unwritable folder,
    a read-only or special file, a loop of symbolic links.

    Parameters
    ----------
    path : path-like
        Where the command will write.
    suffixes : tuple of str
        The allowed endings, e.g. ``(".ply", ".npz")``.
    """
    if not str(path).strip():  # Path("") is ".", a folder: the message would name the current folder
        raise UsageError(f"an empty file name; allowed: a file name ending in {', '.join(suffixes)}")
    out = Path(path)
    if out.is_dir():
        raise UsageError(f"{out}: is a folder; allowed: a file name ending in {', '.join(suffixes)}")
    if out.suffix.lower() not in suffixes:
        raise UsageError(f"{out}: unknown format {out.suffix or '(none)'}; allowed: {', '.join(suffixes)}")
    folder = resolve_destination(out).parent
    if not os.access(folder, os.W_OK):
        raise UsageError(f"{out}: the folder {folder.absolute()} is not writable")
    return out


def check_bag_path(path: str | Path, *others: str | Path | None) -> Path:
    """Refuse a ``--rosbag`` folder before any work: it must be a new name (not even a dangling link) in a
    writable folder, and not the same path as another output of the command (``others``)."""
    bag = Path(path)
    if os.path.lexists(bag):
        what = "a symbolic link" if bag.is_symlink() else "a folder" if bag.is_dir() else "a file"
        raise UsageError(f"--rosbag {path}: exists ({what}); allowed: a new folder name (nothing is replaced)")
    folder = bag.absolute().parent
    if not folder.is_dir():
        raise UsageError(f"--rosbag {path}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise UsageError(f"--rosbag {path}: the folder {folder} is not writable")
    for other in filter(None, others):
        if os.path.realpath(other) == os.path.realpath(bag):
            raise UsageError(f"--rosbag {path}: the same path as the output {other}; allowed: a bag folder name "
                             "of its own")
    return bag
