"""What the window writes: screenshots with their JSON sidecars, and user presets."""

from __future__ import annotations

import json
import os
import threading
from collections.abc import Callable
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from livox_viz.config.presets import user_preset_dir
from livox_viz.config.sensor import save_config
from livox_viz.core.atomic import atomic_path, write_text_atomic
from livox_viz.core.errors import LivoxVizError
from livox_viz.core.portable import usable_cores
from livox_viz.core.workload import POINT_BUDGET, check_points
from livox_viz.files.scan_bag import BagWritten, write_scan_bag
from livox_viz.patterns.stream import points_before

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
    from livox_viz.files.lvx_format import LIVOX_FORMATS, head_for_config
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
    # Livox's files hold the sensor's points with the mount as the device's extrinsics, and only a head they know
    # (refused here, before the worker, in one line).
    livox = None
    if target.suffix.lower() in LIVOX_FORMATS:
        livox = head_for_config(target.suffix.lower(), config, session.preset_name or "custom")

    def work() -> int:
        mounted = MountedCaster(config, caster, pose, trajectory, seed)
        pattern = make_pattern(config, seed)
        pattern.skip(first)
        written = 0
        with PointCloudWriter(target, coordinates="world" if livox is None else "sensor", source=made,
                              livox=livox) as writer:
            position = first
            while position < stop:
                count = min(config.points_per_frame - position % config.points_per_frame, stop - position)
                frame = mounted.cast(pattern.take(count))
                writer.write(frame)
                written += len(frame)
                position += count
        return written

    return work


#: Scan seconds a ROS 2 bag exported from the window holds unless the user types another (from t = 0): enough for
#: an odometry to settle, a few seconds' work.
BAG_SECONDS = 10.0
#: The shortest bag the window exports, seconds (one frame of the slowest sensor).
BAG_SHORTEST = 0.1


def bag_longest(session: Session) -> float:
    """The most scan seconds a bag of the session's scan may hold: the point budget's (as ``scan`` checks it), and
    the trajectory's end (there is no pose after it)."""
    longest = POINT_BUDGET / session.config.point_rate
    if session.trajectory is not None:
        longest = min(longest, session.trajectory.span[1])
    return longest


def check_bag_folder(path: Path) -> Path:
    """Refuse a bag folder before any work: it must be a new name in a folder that exists and is writable.

    Raises
    ------
    LivoxVizError
        Naming the path and what is allowed.
    """
    if not str(path).strip():
        raise LivoxVizError("bag not exported: an empty name; allowed: a new folder name")
    if os.path.lexists(path):
        what = "a symbolic link" if path.is_symlink() else "a folder" if path.is_dir() else "a file"
        raise LivoxVizError(f"bag not exported: {path} exists ({what}); allowed: a new folder name (nothing is "
                            "replaced)")
    folder = path.absolute().parent
    if not folder.is_dir():
        raise LivoxVizError(f"bag not exported: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise LivoxVizError(f"bag not exported: the folder {folder} is not writable; allowed: a folder you can "
                            "write in")
    return path


class BagExport:
    """The work of exporting the session's scan as a ROS 2 bag: the scan from t = 0 for ``seconds``, with the
    session's configuration (its return model), scene, vehicle pose, motion and seed, into the bag ``livox-viz
    scan --rosbag`` writes for them (:func:`~livox_viz.files.scan_bag.write_scan_bag`). A worker calls it; the
    window reads :attr:`fraction` and may :meth:`cancel` it (closing: the bag is given up, nothing is kept).

    Raises (on creation)
    --------------------
    LivoxVizError
        A bag the point budget cannot hold, or longer than the trajectory.
    """

    def __init__(self, session: Session, target: Path, seconds: float) -> None:
        check_points(points_before(seconds, session.config.point_rate), f"a bag of {seconds:g} s", can_force=False)
        if session.trajectory is not None:
            session.trajectory.check_covers(0.0, seconds)
        self.target = target
        self.seconds = seconds
        self._scan = (session.config, session.caster, session.vehicle_pose, session.trajectory, session.seed)
        #: The share of the scan written so far, 0 to 1.
        self.fraction = 0.0
        self._cancel = threading.Event()

    def __call__(self) -> BagWritten:
        config, caster, pose, trajectory, seed = self._scan
        # One core left to the window: the scan is the same whatever the count.
        return write_scan_bag(self.target, config, caster, pose, trajectory, seed, self.seconds,
                              workers=max(1, usable_cores() - 1), progress=self._progress,
                              cancelled=self._cancel.is_set)

    def _progress(self, scan_time: float) -> None:
        self.fraction = min(scan_time / self.seconds, 1.0)

    def cancel(self) -> None:
        """Give the bag up after the frame in hand."""
        self._cancel.set()
