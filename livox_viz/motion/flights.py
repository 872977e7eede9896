"""Built-in flights from the vehicle's start pose: ``hover``, ``line``, ``circle``, ``figure8``.

Every flight starts and ends at rest: the speed along the path rises from 0 with a
smootherstep ``S(x) = 6x^5 - 15x^4 + 10x^3`` over :data:`RAMP_SECONDS` (or half the
flight when it is shorter), cruises, and falls back to 0 the same way at the
flight's end. Speed, acceleration and jerk are continuous and zero at both ends,
so a lidar-inertial initialiser sees a vehicle at rest (the IMU reads gravity
only) at the start. The heading follows the path's tangent (a function of the
path parameter, so it is defined at rest too).

The analytic flight is sampled at :data:`BUILTIN_RATE` into a
:class:`~livox_viz.motion.trajectory.Trajectory`, whose C2 spline is the motion
every consumer uses (between 100 Hz samples it is within micrometres of the
analytic path), in the world NED frame of the start pose.
"""

from __future__ import annotations

import math

import numpy as np

from livox_viz.core.errors import LivoxVizError, quoted
from livox_viz.core.poses import Pose
from livox_viz.motion.trajectory import Trajectory

BUILTIN_TRAJECTORIES: tuple[str, ...] = ("hover", "line", "circle", "figure8")

BUILTIN_RATE = 100.0

CIRCLE_RADIUS = 15.0

FIGURE8_SIZE = 20.0

#: Seconds from rest to cruising speed (and back at the end).
RAMP_SECONDS = 2.0

#: The flights' fastest speed, m/s.
MAX_SPEED = 100.0


def ramp_seconds(seconds: float) -> float:
    """How long a built-in flight of ``seconds`` takes to reach its speed (and to stop), s."""
    return min(RAMP_SECONDS, seconds / 2.0)


def path_length(t: np.ndarray, speed: float, seconds: float) -> np.ndarray:
    """``(n,)`` metres along the path at times ``t`` of a flight of ``seconds`` at cruising ``speed`` m/s.

    The speed is ``speed * S(t / ramp)`` while speeding up and ``speed * S((seconds - t) / ramp)`` while
    stopping; the distance integrates it: ``ramp * speed * I(x)`` with ``I(x) = x^6 - 3x^5 + 5x^4 / 2``.
    """
    ramp = ramp_seconds(seconds)

    def integral(x: np.ndarray) -> np.ndarray:
        return x**6 - 3.0 * x**5 + 2.5 * x**4

    t = np.clip(np.asarray(t, dtype=np.float64), 0.0, seconds)
    cruise = 0.5 * ramp * speed + speed * (t - ramp)
    rising = ramp * speed * integral(np.clip(t / ramp, 0.0, 1.0))
    total = speed * (seconds - ramp)
    falling = total - ramp * speed * integral(np.clip((seconds - t) / ramp, 0.0, 1.0))
    return np.where(t < ramp, rising, np.where(t > seconds - ramp, falling, cruise))


#: Nodes per turn of the lemniscate for its arc-length table (the speed is analytic: the error is ~h^4).
FIGURE8_NODES = 1024


def figure8_parameter(s: np.ndarray, a: float) -> np.ndarray:
    """``(n,)`` the parameter u of Gerono's lemniscate ``(a sin u, a sin u cos u)`` after ``s`` metres along it.

    Its speed ``|dr/du| = a sqrt(cos^2 u + cos^2 2u)`` is never zero (between 0.66 a
    and 1.41 a), so the arc length L(u) is smooth and increasing: it is
    integrated once as a periodic spline of the speed, and ``L(u) = s`` is solved by
    Newton steps from a table lookup. A constant parameter rate would fly the
    curve's loops and crossing at different speeds (and its mean is not ``a du/dt``).

    Parameters
    ----------
    s : (n,) float64
        Metres along the path from u = 0, >= 0.
    a : float
        Half the lemniscate's length, metres.
    """
    from scipy.interpolate import CubicSpline

    def speed(u: np.ndarray) -> np.ndarray:
        return a * np.hypot(np.cos(u), np.cos(2.0 * u))

    nodes = np.linspace(0.0, 2.0 * np.pi, FIGURE8_NODES + 1)
    length = CubicSpline(nodes, speed(nodes), bc_type="periodic").antiderivative()
    turn = float(length(2.0 * np.pi))
    s = np.asarray(s, dtype=np.float64)
    turns, rest = np.divmod(s, turn)
    u = np.interp(rest, length(nodes), nodes)
    for _ in range(2):  # quadratic convergence: from ~1e-5 rad to rounding
        u -= (length(u) - rest) / speed(u)
    return u + 2.0 * np.pi * turns


def builtin_trajectory(name: str, speed: float, start: Pose, seconds: float) -> Trajectory:
    """A built-in flight from ``start``, ``seconds`` long, from rest to rest, sampled at :data:`BUILTIN_RATE`.

    Parameters
    ----------
    name : {"hover", "line", "circle", "figure8"}
        ``hover`` stays; ``line`` flies straight ahead; ``circle`` turns right on a
        15 m circle facing along the path; ``figure8`` flies a 20 m lemniscate
        (Gerono's, by arc length: at ``speed`` all along it while cruising).
    speed : float
        Cruising speed, m/s.
    start : Pose
        The vehicle's pose at t = 0 (NED).
    seconds : float
        How long, s; the vehicle is at rest again at its end.
    """
    if name not in BUILTIN_TRAJECTORIES:
        raise LivoxVizError(f"trajectory {quoted(name)}; allowed: a TUM file or a built-in flight: "
                            f"{', '.join(BUILTIN_TRAJECTORIES)}")
    if not (math.isfinite(speed) and 0 <= speed <= MAX_SPEED):
        raise LivoxVizError(f"--trajectory-speed {quoted(speed)}; allowed: 0 to {MAX_SPEED:g} m/s")
    if not (math.isfinite(seconds) and seconds > 0):
        raise LivoxVizError(f"a built-in flight of {quoted(seconds)} s; allowed: a finite time > 0")
    count = max(2, math.ceil(seconds * BUILTIN_RATE) + 1)
    t = np.linspace(0.0, seconds, count)
    s = path_length(t, speed if name != "hover" else 0.0, seconds)
    heading = start.yaw
    forward = np.array([math.cos(heading), math.sin(heading), 0.0])
    right = np.array([-math.sin(heading), math.cos(heading), 0.0])
    yaw = np.full(count, heading)
    if name in ("hover", "line"):
        local = np.column_stack([s, np.zeros(count)])
    elif name == "circle":
        angle = s / CIRCLE_RADIUS
        local = CIRCLE_RADIUS * np.column_stack([np.sin(angle), 1.0 - np.cos(angle)])
        yaw = heading + angle
    else:
        # Gerono's lemniscate x = a sin(u), y = a sin(u) cos(u), at the parameter u whose arc length is s.
        a = FIGURE8_SIZE / 2
        u = figure8_parameter(s, a)
        local = np.column_stack([a * np.sin(u), a * np.sin(u) * np.cos(u)])
        yaw = heading + np.unwrap(np.arctan2(np.cos(2 * u), np.cos(u)))
    position = start.origin + local[:, :1] * forward + local[:, 1:] * right
    from scipy.spatial.transform import Rotation

    tilt = Rotation.from_euler("ZYX", [0.0, start.pitch, start.roll])
    orientation = Rotation.from_rotvec(np.outer(yaw, [0.0, 0.0, 1.0])) * tilt
    label = "hovering" if name == "hover" or speed == 0 else f"{name} at {speed:g} m/s"
    return Trajectory(label, t, position, orientation.as_quat())
