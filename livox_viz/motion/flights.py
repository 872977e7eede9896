"""Built-in flights from the vehicle's start pose: ``hover``, ``line``, ``circle``, ``figure8``.

Every flight starts and ends at rest: the speed along the path rises from 0 with a
smootherstep ``S(x) = 6x^5 - 15x^4 + 10x^3`` over :data:`RAMP_SECONDS` (or half the
flight when it is shorter), cruises, and falls back to 0 the same way at the
flight's end. Speed, acceleration and jerk are continuous and zero at both ends,
so a lidar-inertial initialiser sees a vehicle at rest (the IMU reads gravity
only) at the start. The heading follows the path's tangent (a function of the
path parameter, so it is defined at rest too).

The turns are sized for a rate a real multicopter flies and a lidar odometry
follows: at the default 5 m/s the ``circle`` (15 m radius) yaws at 0.33 rad/s and
the ``figure8`` (Bernoulli's lemniscate, 32 m long, whose sharpest turn is 3 / a
with a its half length) at most 0.94 rad/s (:func:`peak_yaw_rate`; both grow with
the speed). Gerono's 20 m lemniscate, flown before, turned at 2.4 rad/s there
(13.7 degrees a frame).

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

#: The circle's radius, metres.
CIRCLE_RADIUS = 15.0

#: The figure-8's length tip to tip, metres (Bernoulli's lemniscate: 2 a long, a / sqrt(2) wide).
FIGURE8_SIZE = 32.0

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


def peak_yaw_rate(name: str, speed: float) -> float:
    """The fastest a built-in flight turns while cruising at ``speed`` m/s, rad/s: speed x its sharpest curvature."""
    curvature = {"circle": 1.0 / CIRCLE_RADIUS, "figure8": 3.0 / (FIGURE8_SIZE / 2)}.get(name, 0.0)
    return speed * curvature


def figure8_point(u: np.ndarray, a: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bernoulli's lemniscate ``(a sin u, a sin u cos u) / (1 + cos^2 u)`` at parameter ``u``: x, y (m) and the
    heading of its tangent (rad, unwrapped). It crosses itself at u = 0 heading 45 degrees to the right and turns
    sharpest at its tips (curvature 3 / a)."""
    u = np.asarray(u, dtype=np.float64)
    cos, sin = np.cos(u), np.sin(u)
    scale = a / (1.0 + cos * cos)
    # dx/du = a cos u (3 - cos^2 u) / D^2 and dy/du = a (3 cos^2 u - 1) / D^2, D = 1 + cos^2 u.
    heading = np.unwrap(np.arctan2(3.0 * cos * cos - 1.0, cos * (3.0 - cos * cos)))
    return scale * sin, scale * sin * cos, heading


def figure8_parameter(s: np.ndarray, a: float) -> np.ndarray:
    """``(n,)`` the parameter u of Bernoulli's lemniscate (:func:`figure8_point`) after ``s`` metres along it.

    Its speed ``|dr/du| = a / sqrt(1 + cos^2 u)`` is never zero (between 0.71 a
    and a), so the arc length L(u) is smooth and increasing: it is
    integrated once as a periodic spline of the speed, and ``L(u) = s`` is solved by
    Newton steps from a table lookup. A constant parameter rate would fly the
    curve's loops and crossing at different speeds.

    Parameters
    ----------
    s : (n,) float64
        Metres along the path from u = 0, >= 0.
    a : float
        Half the lemniscate's length, metres.
    """
    from scipy.interpolate import CubicSpline

    def speed(u: np.ndarray) -> np.ndarray:
        return a / np.sqrt(1.0 + np.cos(u) ** 2)

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
        15 m circle facing along the path; ``figure8`` flies a 32 m lemniscate
        (Bernoulli's, by arc length: at ``speed`` all along it while cruising).
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
        # Bernoulli's lemniscate at the parameter u whose arc length is s.
        x, y, tangent = figure8_point(figure8_parameter(s, FIGURE8_SIZE / 2), FIGURE8_SIZE / 2)
        local = np.column_stack([x, y])
        yaw = heading + tangent
    position = start.origin + local[:, :1] * forward + local[:, 1:] * right
    from scipy.spatial.transform import Rotation

    tilt = Rotation.from_euler("ZYX", [0.0, start.pitch, start.roll])
    orientation = Rotation.from_rotvec(np.outer(yaw, [0.0, 0.0, 1.0])) * tilt
    label = "hovering" if name == "hover" or speed == 0 else f"{name} at {speed:g} m/s"
    return Trajectory(label, t, position, orientation.as_quat())
