"""The GUI's commands for the ``livox-viz`` command line: ``gui`` (the default) and ``render``."""

from __future__ import annotations

import argparse
from datetime import datetime
from pathlib import Path

from livox_viz.cli import PROG, UsageError, config_from_args, config_label, scene_from_args


def _session(args: argparse.Namespace):
    from .session import Session

    config = config_from_args(args)
    scene, pose = scene_from_args(args)
    session = Session(config, scene, seed=args.seed, preset_name=config_label(args), vehicle_pose=pose)
    if getattr(args, "reference", None):
        from livox_viz.reference import load_reference

        session.set_reference(load_reference(args.reference, rate=args.reference_rate))
    return session


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise UsageError(f"--size {text!r}; allowed: WIDTHxHEIGHT in pixels, e.g. 1600x900") from None
    if not (64 <= width <= 8192 and 64 <= height <= 8192):
        raise UsageError(f"--size {text!r}; allowed: 64 to 8192 pixels each way")
    return width, height


def cmd_gui(args: argparse.Namespace) -> int:
    from .app import LivoxVizApp, has_display, render_offscreen

    session = _session(args)
    if not has_display():
        folder = Path("screenshots")
        folder.mkdir(parents=True, exist_ok=True)
        stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
        print(f"{PROG}: no display (DISPLAY is not set): rendering the views off-screen into {folder}/ instead")
        for views in ("both", "pattern", "scene"):
            path = folder / f"offscreen-{stamp}-{views}.png"
            session.restart()
            size = (1600, 900) if views == "both" else (900, 900)
            render_offscreen(session, args.seconds, path, views=views, size=size)
            print(f"  {path}")
        return 0
    app = LivoxVizApp(session, window_size=_size(args.size))
    app.show()
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from .app import render_offscreen

    out = Path(args.out)
    if out.suffix.lower() != ".png":
        raise UsageError(f"--out {out}: allowed: a .png file")
    size = _size(args.size)
    session = _session(args)
    render_offscreen(session, args.seconds, out, views=args.view, size=size)
    print(f"rendered {args.view} after {args.seconds:g} s of scan time to {out} ({size[0]}x{size[1]})")
    return 0


def run_listen_gui(receiver, config, args: argparse.Namespace) -> int:
    """``listen --gui``: show received frames in both views until the window closes."""
    from livox_viz.scene import open_scene

    from .app import LivoxVizApp, has_display
    from .session import Session

    if not has_display():
        raise UsageError("listen --gui needs a display (DISPLAY is not set); record with --record instead")
    scene = open_scene(args.scene)
    session = Session(config, scene, preset_name="received", vehicle_pose=scene.vehicle_pose)
    session.source = receiver
    session.message = f"listening on {args.host}:{args.port}" if not args.shm else "listening on shared memory"
    app = LivoxVizApp(session, window_size=(1600, 900))
    app.show()
    return 0
