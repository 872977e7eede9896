"""The GUI's commands, registered into ``livox-viz`` through the ``livox_viz.commands`` entry point.

``gui`` (the default command) opens the window; ``render`` draws what it
shows off-screen into a PNG. This module imports no VTK: the commands import
the window only when they run, so the model's commands stay light.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from livox_viz.cli.common import (
    PROG,
    Command,
    UsageError,
    add_config_arguments,
    add_scene_arguments,
    add_seed_argument,
    add_trajectory_arguments,
    check_output_path,
    config_from_args,
    config_label,
    positive_float,
    scene_from_args,
    scene_reflectance,
    trajectory_from_args,
)
from livox_viz.cli.signals import StopRequests, signal_name, signal_status
from livox_viz.cli.wire_commands import add_receiver_arguments, open_receiver
from livox_viz.core.errors import LivoxVizError, quoted
from livox_viz.core.workload import WINDOW_BUDGET, check_points
from livox_viz.patterns.stream import points_before
from livox_viz.scene.materials import DEFAULT_REFLECTANCE


def _session(args: argparse.Namespace, command: str):
    from .session import Session, check_window

    config = config_from_args(args)
    check_window(config)
    # The picture after S seconds draws the pattern's S seconds (its random draws run in order), and a flight lasts
    # them: the scan's budget, checked before any of it.
    check_points(points_before(args.seconds, config.point_rate), f"{command} --seconds {args.seconds:g}",
                 can_force=False)
    scene, pose, caster = scene_from_args(args, config if command == "render" else None)  # gui: `d` switches
    # The window plays on: a built-in flight lasts two minutes, or the render's seconds.
    trajectory = trajectory_from_args(args, pose, max(args.seconds, GUI_FLIGHT_SECONDS), whole_file=True)
    session = Session(config, scene, seed=args.seed, preset_name=config_label(args), vehicle_pose=pose,
                      caster=caster, trajectory=trajectory)
    session.scene_options = {"up": args.up, "reflectance": scene_reflectance(args)}
    session.sources = {"scene": args.scene, "up": args.up, "reflectance": scene_reflectance(args), "pose": args.pose,
                       "exact": args.exact, "trajectory": args.trajectory, "trajectory_speed": args.trajectory_speed,
                       "reference": getattr(args, "reference", None),
                       "reference_rate": getattr(args, "reference_rate", None)}
    session.display.scene_colour = args.scene_colour
    if args.reference is None and args.reference_rate is not None:
        raise UsageError("--reference-rate without --reference; allowed: with --reference TABLE (its rows per "
                         "second)")
    if args.reference is not None:
        source = reference_source(args.reference, args.reference_rate, args.seed, float(config.point_rate))
        _check_reference(source, args)
        if source.plane != config.pattern_plane:
            raise LivoxVizError(f"--reference {args.reference} is a {source.plane} pattern and "
                                f"{config_label(args)} a {config.pattern_plane} one; allowed: a reference in the "
                                "same plane (a 360-degree head's azimuth/elevation is not a boresight pattern)")
        session.overlay.set_source(source, 0.0)
    return session


GUI_FLIGHT_SECONDS = 120.0


def _check_reference(source, args: argparse.Namespace) -> None:
    """Refuse a reference the overlay cannot play, as ``compare`` does: a table shorter than compare's shortest
    window, a rate given to a preset (which plays at its own), or one whose integration windows would hold more
    than the window's budget (1e12 rows/s asked for 5.46 TiB)."""
    from livox_viz.fitting.compare import COMPARE_TIMES

    from .overlay import WINDOWS, TableSource, window_capacity, window_label

    rate = f" at {source.rate:g} rows/s" + (" (--reference-rate)" if args.reference_rate is not None else "")
    if isinstance(source, TableSource):
        if source.table.seconds < min(COMPARE_TIMES):
            raise UsageError(f"--reference {args.reference}: the table holds {source.table.seconds:.3g} s{rate}; "
                             f"allowed: at least {min(COMPARE_TIMES):g} s")
    elif args.reference_rate is not None:
        raise UsageError(f"--reference-rate with the preset {args.reference}; allowed: with a table (a preset plays "
                         "at its own point rate)")
    for window in WINDOWS:
        check_points(window_capacity(window, source.rate), f"--reference {args.reference}{rate}: the overlay's "
                     f"{window_label(window)} window", WINDOW_BUDGET, can_force=False)


def reference_source(text: str, rate: float | None, seed: int = 0, recording_rate: float | None = None):
    """``--reference``: a measured table (.npy / .npz / Livox .csv), a real sensor's recording (.pcd / .ply / x,y,z
    .csv / .lvx2 / .lvx / .bag; one without per-point times at ``recording_rate``, the head's points per second) or
    a preset (a name or a sensor JSON)."""
    from livox_viz import load_preset
    from livox_viz.fitting.reference import is_table, load_reference

    from .overlay import PresetSource, TableSource

    if Path(text).is_dir() and Path(text).suffix.lower() != ".bag":
        raise LivoxVizError(f"{text}: is a folder; allowed: a table (.npy, .npz or Livox .csv), a recording (.pcd, "
                            ".ply, x,y,z .csv, .lvx2, .lvx or .bag) or a preset (name or .json)")
    if is_table(text):
        return TableSource(load_reference(text, rate=rate, recording_rate=recording_rate))
    return PresetSource(load_preset(text), Path(text).stem, seed)


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise UsageError(f"--size {quoted(text)}; allowed: WIDTHxHEIGHT in pixels, e.g. 1600x900") from None
    if not (64 <= width <= 8192 and 64 <= height <= 8192):
        raise UsageError(f"--size {quoted(text)}; allowed: 64 to 8192 pixels each way")
    return width, height


#: Where ``gui`` without a display puts its pictures (one set, overwritten by the next run).
OFFSCREEN_DIR = Path("offscreen")


def _check_covered(session, seconds: float) -> None:
    """Refuse a picture after ``seconds`` when the trajectory ends before (it would show its end)."""
    if session.trajectory is not None:
        session.trajectory.check_covers(0.0, seconds)


def cmd_gui(args: argparse.Namespace) -> int:
    from .display import display_problem

    size = _size(args.size)
    problem = display_problem(waiting=lambda words: print(f"{PROG}: {words}", file=sys.stderr, flush=True))
    if args.listen and problem:
        raise UsageError(f"gui --listen needs a display ({problem}); record with 'listen --record' instead")
    if problem:
        from .app import render_offscreen

        session = _session(args, "gui")
        _check_covered(session, args.seconds)
        folder = Path(args.offscreen_dir)
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise UsageError(f"no display, and the folder {folder.resolve()} for off-screen pictures cannot be "
                             f"made ({exc.strerror})") from None
        print(f"{PROG}: no display ({problem}): rendering the views off-screen into {folder}/ instead")
        for views in ("both", "pattern", "scene"):
            path = folder / f"{views}.png"
            session.restart()
            square = (min(size),) * 2
            render_offscreen(session, args.seconds, path, views=views, size=size if views == "both" else square)
            print(f"  {path}")
        return 0
    from livox_viz.casting.warm import STAGES, stages_for

    from .live import LiveStats
    from .mainwindow import run_window
    from .warmup import LoopWarmer

    # The compiled loops start loading once the window has drawn its first frame (widgets/warmup.py says why).
    warmer = LoopWarmer(stages_for(config_from_args(args), bool(args.trajectory)), STAGES)

    session = _session(args, "gui")
    receiver = None
    if args.listen:
        receiver, where = open_receiver(args, session.config)
        session.source = receiver
        session.live = LiveStats(where)
        session.preset_name = "received"
    # Ctrl-C, SIGTERM and SIGHUP close the window on its next tick (raised inside Qt's loop, they would be lost).
    with StopRequests() as stop:
        try:
            run_window(session, size, stop=lambda: stop.requested, warmer=warmer)
        finally:
            warmer.close()
            if receiver is not None:
                receiver.close()
    if stop.signum is not None:
        print(f"{PROG}: stopped by {signal_name(stop.signum)}", file=sys.stderr)
        return signal_status(stop.signum)
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from .app import render_offscreen

    out = check_output_path(args.out, (".png",))
    if args.sidecar:
        return _render_sidecar(args, out)
    size = _size(args.size)
    session = _session(args, "render")
    _check_covered(session, args.seconds)
    render_offscreen(session, args.seconds, out, views=args.view, size=size)
    print(f"rendered {args.view} after {args.seconds:g} s of scan time to {out} ({size[0]}x{size[1]})")
    return 0


def _render_sidecar(args: argparse.Namespace, out: Path) -> int:
    """``render --sidecar FILE``: the picture a screenshot's sidecar describes, drawn again."""
    from livox_viz.config.sensor import SensorConfig
    from livox_viz.core.jsonfile import read_json_file

    from .app import VIEW_NAMES, render_offscreen
    from .files import SIDECAR_VERSION
    from .overlay import WINDOWS
    from .session import Session

    path = Path(args.sidecar)
    data = read_json_file(path, "screenshot sidecar")
    if not isinstance(data, dict) or not isinstance(data.get("livox_viz_sidecar"), int):
        raise UsageError(f"--sidecar {path}: not a livox-viz screenshot sidecar (no 'livox_viz_sidecar' version); "
                         "allowed: the .json written beside a screenshot")
    if data["livox_viz_sidecar"] > SIDECAR_VERSION:
        raise UsageError(f"--sidecar {path}: format {data['livox_viz_sidecar']} is newer than this livox-viz reads "
                         f"({SIDECAR_VERSION}); update livox-viz")
    try:
        config = SensorConfig.from_json_dict(data["config"])
        sources = dict(data.get("sources") or {})
        seconds = float(data["scan_time_s"])
        sizes = {name: tuple(int(v) for v in data["view_sizes"][name]) for name in VIEW_NAMES
                 if name in data["view_sizes"]}
        cameras, drawing = data.get("cameras") or {}, data.get("views") or {}
    except (KeyError, TypeError, ValueError) as exc:
        raise UsageError(f"--sidecar {path}: missing or malformed {exc}; allowed: a sidecar as livox-viz writes it"
                         ) from None
    for name, size in sizes.items():
        if not all(64 <= v <= 8192 for v in size):
            raise UsageError(f"--sidecar {path}: the {name} view is {size[0]}x{size[1]}; allowed: 64 to 8192 pixels")
    scene_args = argparse.Namespace(
        scene=sources.get("scene") or data.get("scene") or "urban", up=sources.get("up") or "z",
        pose=sources.get("pose"), exact=bool(sources.get("exact")),
        reflectance=sources.get("reflectance") if sources.get("reflectance") is not None else DEFAULT_REFLECTANCE,
        trajectory=sources.get("trajectory"), trajectory_speed=sources.get("trajectory_speed"))
    check_points(points_before(seconds, config.point_rate), f"render --sidecar at {seconds:g} s", can_force=False)
    scene, pose, caster = scene_from_args(scene_args)
    trajectory = trajectory_from_args(scene_args, pose, max(seconds, GUI_FLIGHT_SECONDS), whole_file=True)
    session = Session(config, scene, seed=int(data.get("seed", 0)), preset_name=str(data.get("preset") or ""),
                      vehicle_pose=pose, caster=caster, trajectory=trajectory)
    session.sources = sources
    session.set_window_seconds(data.get("window_s"))
    display = session.display
    display.pattern_colour = data.get("pattern_colour", display.pattern_colour)
    display.scene_colour = data.get("scene_colour", display.scene_colour)
    display.drawing = data.get("drawing", display.drawing)
    display.cloud_frame = data.get("cloud_frame", display.cloud_frame)
    reference = sources.get("reference") or data.get("reference")
    if reference:
        rate = sources.get("reference_rate")
        if rate is not None and (isinstance(rate, bool) or not isinstance(rate, (int, float)) or not rate > 0):
            raise UsageError(f"--sidecar {path}: reference_rate = {quoted(rate)}; allowed: rows per second > 0")
        source = reference_source(str(reference), rate, session.seed, float(session.config.point_rate))
        _check_reference(source, argparse.Namespace(reference=str(reference), reference_rate=rate))
        session.overlay.set_source(source, 0.0)
        session.overlay.visible = bool(data.get("reference_visible", True))
        window = data.get("reference_window_s")
        if window in WINDOWS:
            session.overlay.window_index = WINDOWS.index(window)

    def prepare(app) -> None:
        app.apply_drawing_state(drawing)
        app.apply_cameras(cameras)

    views = "both" if len(sizes) == 3 else next(iter(sizes))
    render_offscreen(session, seconds, out, views=views, sizes=sizes, prepare=prepare)
    width = sum(size[0] for size in sizes.values())
    print(f"rendered {path.name}'s picture after {seconds:g} s of scan time to {out} "
          f"({width}x{max(size[1] for size in sizes.values())})")
    return 0


#: The scene view's colours (``session.SCENE_COLOURS``, which a test holds equal): written out so that building
#: the command line imports no session.
SCENE_COLOUR_CHOICES = ("range", "height", "time", "reflectivity", "return/tag")


def _common_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_arguments(parser)
    add_scene_arguments(parser)
    add_trajectory_arguments(parser)
    add_seed_argument(parser)
    parser.add_argument("--scene-colour", choices=SCENE_COLOUR_CHOICES, default="range",
                        help="what colours the cloud in the scene view (k cycles them in the window): range, height, "
                             "time, reflectivity (byte, log scale) or return/tag (default range)")
    parser.add_argument("--reference", help="overlay a reference in the pattern view: a scan table (mid40, mid70, "
                                            "a .npy in radians or a Livox CSV) or a preset (e.g. livox_mid70_risley)")
    parser.add_argument("--reference-rate", type=positive_float,
                        help="rows per second of a reference table (default: the shipped index's rate, else the rows' "
                             "own times, else the rate read from the spectrum, as fit does)")


def _gui_arguments(parser: argparse.ArgumentParser) -> None:
    _common_arguments(parser)
    parser.add_argument("--size", default="1600x900", help="window size WIDTHxHEIGHT (default 1600x900)")
    parser.add_argument("--seconds", type=positive_float, default=1.0,
                        help="scan time of the off-screen pictures when there is no display (default 1)")
    parser.add_argument("--offscreen-dir", default=str(OFFSCREEN_DIR),
                        help="where the off-screen pictures go when there is no display: both.png, pattern.png and "
                             f"scene.png, replaced on every run (default {OFFSCREEN_DIR}/)")
    parser.add_argument("--listen", action="store_true",
                        help="show the frames received on --port (RflySim or 'livox-viz publish') instead of the "
                             "model; with --shm, those in shared memory")
    add_receiver_arguments(parser)


def _render_arguments(parser: argparse.ArgumentParser) -> None:
    _common_arguments(parser)
    parser.add_argument("--seconds", type=positive_float, default=1.0, help="scan time (default 1)")
    parser.add_argument("--view", choices=("pattern", "scene", "both"), default="both",
                        help="which view (default both)")
    parser.add_argument("--size", default="1600x900", help="image size WIDTHxHEIGHT (default 1600x900)")
    parser.add_argument("--out", required=True, help="output PNG")
    parser.add_argument("--sidecar", help="draw the picture a screenshot's JSON sidecar describes (configuration, "
                                          "scan time, window, colours, cameras, scene, reference: all from the file; "
                                          "the other options are not used)")


COMMANDS: tuple[Command, ...] = (
    Command("gui", cmd_gui, "open the interactive window (the default command)",
            "livox-viz gui --preset livox_mid70 --scene urban", _gui_arguments, default=True),
    Command("render", cmd_render, "render what the GUI shows after S seconds into a PNG, off-screen",
            "livox-viz render --view both --seconds 1 --out screenshots/both.png", _render_arguments),
)
