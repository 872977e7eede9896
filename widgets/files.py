"""What the window writes: screenshots with their JSON sidecars, and user presets."""

from __future__ import annotations

import json
from collections.abc import Callable
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from livox_viz.config.presets import user_preset_dir
from livox_viz.config.sensor import save_config
from livox_viz.core.atomic import atomic_path, write_text_atomic
from livox_viz.core.errors import LivoxVizError

from .session import Session

SCREENSHOT_DIR = Path("screenshots")


def write_png(image: np.ndarray, path: Path) -> Path:
    """Write an ``(h, w, 3|4)`` uint8 image as PNG, atomically."""
    from PIL import Image

    with atomic_path(path) as tmp:
        # zlib level 1: a 1600x900 window in 70 ms instead of 110 ms, the file a tenth larger.
        Image.fromarray(np.asarray(image)).save(tmp, format="PNG", compress_level=1)
    return path


def unused_screenshot_path(folder: Path) -> Path:
    """``folder/livox-viz-<time>.png``, numbered if that exists already (the folder is created).

    Raises
    ------
    LivoxVizError
        Naming the folder, when it cannot be made (a file in its place, a read-only parent).
    """
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise LivoxVizError(f"screenshot not saved: cannot make the folder {folder} ({exc.strerror or exc})") from None
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S-%f")[:-3]
    path = folder / f"livox-viz-{stamp}.png"
    suffix = 1
    while path.exists():
        path = folder / f"livox-viz-{stamp}-{suffix}.png"
        suffix += 1
    return path


#: The sidecar's format: bumped when a key changes meaning (``render --sidecar`` refuses a newer one).
SIDECAR_VERSION = 2


def sidecar(session: Session, drawing: dict[str, Any], cameras: dict[str, Any],
            view_sizes: dict[str, list[int]]) -> dict[str, Any]:
    """What a screenshot's JSON sidecar holds: everything ``livox-viz render --sidecar`` needs to draw the same
    picture again.

    Parameters
    ----------
    session : Session
    drawing : dict
        The views' own drawing state (colour maps, point sizes, follow, grid, axes; see the controller).
    cameras : dict
        Each view's camera.
    view_sizes : dict
        Each part's pixels, ``{"pattern": [w, h], ...}``: the picture is these side by side.
    """
    from livox_viz import __version__

    overlay = session.overlay
    source = overlay.source
    return {
        "livox_viz_sidecar": SIDECAR_VERSION, "livox_viz_version": __version__,
        "preset": session.preset_name, "config": session.config.to_json_dict(),
        "returns_model": session.config.returns_model, "pattern_model": session.config.pattern_model,
        "seed": session.seed, "scan_time_s": session.scan_time, "window_s": session.window,
        "speed": session.playback.speed, "paused": session.playback.paused,
        "scene": session.scene.name, "vehicle_pose": session.vehicle_pose.as_array().tolist(),
        "sources": dict(session.sources),
        "pattern_colour": session.display.pattern_colour, "scene_colour": session.display.scene_colour,
        "drawing": session.display.drawing, "cloud_frame": session.display.cloud_frame,
        "step_unit": session.display.step_unit, "views": drawing,
        "reference": source.name if source is not None else None,
        "reference_source": session.sources.get("reference") if source is not None else None,
        "reference_rate": source.rate if source is not None else None,
        "reference_visible": overlay.visible, "reference_window_s": overlay.window,
        "cameras": cameras, "view_sizes": view_sizes,
        "window_size": [sum(size[0] for size in view_sizes.values()),
                        max((size[1] for size in view_sizes.values()), default=0)],
    }


def write_sidecar(path: Path, data: dict[str, Any]) -> Path:
    """The sidecar beside the PNG, atomically."""
    target = path.with_suffix(".json")
    write_text_atomic(target, json.dumps(data, indent=2) + "\n")
    return target


def save_user_preset(session: Session) -> Path:
    """Write the current configuration as a user preset (never over a shipped one)."""
    folder = user_preset_dir()
    folder.mkdir(parents=True, exist_ok=True)
    base = (session.preset_name or "custom").split("-tuned-")[0]
    path = folder / f"{base}-tuned-{datetime.now().strftime('%Y%m%d-%H%M%S')}.json"
    suffix = 1
    while path.exists():
        path = path.with_name(f"{base}-tuned-{datetime.now().strftime('%Y%m%d-%H%M%S')}-{suffix}.json")
        suffix += 1
    save_config(session.config, path)
    return path


def window_export(session: Session, target: Path) -> Callable[[], int]:
    """The work of exporting the session's window: cast its span of the stream again into ``target`` (a worker
    runs it; it returns the points written)."""
    from livox_viz.casting.scan import MountedCaster
    from livox_viz.files.export import PointCloudWriter
    from livox_viz.patterns.factory import make_pattern
    from livox_viz.patterns.stream import points_before

    config, seed, caster = session.config, session.seed, session.caster
    pose, trajectory = session.vehicle_pose, session.trajectory
    rate = config.point_rate
    end = session.scan_time
    start = 0.0 if session.window is None else max(0.0, end - session.window)
    first, stop = points_before(start, rate), points_before(end, rate)
    if session.window is None:
        first = max(first, stop - session.pattern_ring.capacity)
    made = (f"livox-viz window export of {session.preset_name or 'custom'} ({config.returns_model} returns, seed "
            f"{seed}) in {session.scene.name}, t = {first / rate:g} to {stop / rate:g} s")

    def work() -> int:
        mounted = MountedCaster(config, caster, pose, trajectory, seed)
        pattern = make_pattern(config, seed)
        pattern.skip(first)
        written = 0
        with PointCloudWriter(target, coordinates="world", source=made) as writer:
            position = first
            while position < stop:
                count = min(config.points_per_frame - position % config.points_per_frame, stop - position)
                frame = mounted.cast(pattern.take(count))
                writer.write(frame)
                written += len(frame)
                position += count
        return written

    return work
