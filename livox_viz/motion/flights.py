"""Built-in flights from the vehicle's start pose: ``hover``, ``line``, ``circle``, ``figure8``.

Sampled at :data:`BUILTIN_RATE` (between samples a 15 m circle at 5 m/s is off its
chord by 0.02 mm, the turn exact), in the world NED frame of the start pose.
"""

from __future__ import annotations

import math

import numpy as np

from livox_viz.core.errors import LivoxVizError
from livox_viz.core.poses import Pose
from livox_viz.motion.trajectory import Trajectory

BUILTIN_TRAJECTORIES: tuple[str, ...] = ("hover", "line", "circle", "figure8")


BUILTIN_RATE = 100.0


CIRCLE_RADIUS = 15.0


FIGURE8_SIZE = 20.0


def builtin_trajectory(name: str, speed: float, start: Pose, seconds: float) -> Trajectory:
    """A built-in flight from ``start``, ``seconds`` long, sampled at :data:`BUILTIN_RATE`.

    Parameters
    ----------
    name : {"hover", "line", "circle", "figure8"}
        ``hover`` stays; ``line`` flies straight ahead at ``speed``; ``circle``
        turns right on a 15 m circle at ``speed`` facing along the path;
        ``figure8`` flies a 20 m lemniscate at a mean speed of about ``speed``.
    speed : float
        m/s.
    start : Pose
        The vehicle's pose at t = 0 (NED).
    seconds : float
        How long, s.
    """
    if name not in BUILTIN_TRAJECTORIES:
        raise LivoxVizError(f"trajectory {name!r}; allowed: a TUM file or {', '.join(BUILTIN_TRAJECTORIES)}")
    if not (math.isfinite(speed) and 0 <= speed <= 100):
        raise LivoxVizError(f"--speed {speed!r}; allowed: 0 to 100 m/s")
    count = max(2, math.ceil(seconds * BUILTIN_RATE) + 1)
    t = np.arange(count) / BUILTIN_RATE
    heading = start.yaw
    forward = np.array([math.cos(heading), math.sin(heading), 0.0])
    right = np.array([-math.sin(heading), math.cos(heading), 0.0])
    yaw = np.full(count, heading)
    if name == "hover":
        local = np.zeros((count, 2))
    elif name == "line":
        local = np.column_stack([speed * t, np.zeros(count)])
    elif name == "circle":
        rate = speed / CIRCLE_RADIUS
        local = CIRCLE_RADIUS * np.column_stack([np.sin(rate * t), 1.0 - np.cos(rate * t)])
        yaw = heading + rate * t
    else:
        # Gerono's lemniscate x = a sin(wt), y = a sin(wt) cos(wt); its mean speed is about 1.22 a w.
        rate = speed / (1.22 * FIGURE8_SIZE / 2) if speed > 0 else 0.0
        a = FIGURE8_SIZE / 2
        local = np.column_stack([a * np.sin(rate * t), a * np.sin(rate * t) * np.cos(rate * t)])
        velocity = np.column_stack([a * rate * np.cos(rate * t), a * rate * np.cos(2 * rate * t)])
        yaw = heading + np.arctan2(velocity[:, 1], velocity[:, 0])
    position = start.origin + local[:, :1] * forward + local[:, 1:] * right
    from scipy.spatial.transform import Rotation

    tilt = Rotation.from_euler("ZYX", [0.0, start.pitch, start.roll])
    orientation = Rotation.from_rotvec(np.outer(yaw, [0.0, 0.0, 1.0])) * tilt
    return Trajectory(f"{name} at {speed:g} m/s", t, position, orientation.as_quat())
