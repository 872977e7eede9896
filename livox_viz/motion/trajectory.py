"""A moving vehicle: trajectories in the world NED frame, interpolated to every point's own time.

A trajectory is a time series of vehicle poses (body FRD in world NED, metres;
orientation as a unit quaternion ``[qx, qy, qz, qw]`` rotating body vectors into
the world), t in seconds from the scan start. Between two poses the position
is linear and the orientation spherical-linear (slerp), evaluated for a
million points at once with numpy quaternions (scipy's ``Slerp`` gives the
same rotations, and is the tests' reference, but costs about 1.3 us a point).

Sources: TUM files (:mod:`~livox_viz.motion.tum`) and the built-in flights
(:mod:`~livox_viz.motion.flights`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from livox_viz.core.errors import LivoxVizError
from livox_viz.core.poses import Pose
from livox_viz.core.rotations import quat_conjugate, quat_multiply


@dataclass(frozen=True)
class Trajectory:
    """Vehicle poses over time, interpolated to any time inside their span.

    Parameters
    ----------
    name : str
    t : (n,) float64
        Seconds from the scan start, strictly increasing.
    position : (n, 3) float64
        Vehicle position, world NED, metres.
    quaternion : (n, 4) float64
        Vehicle orientation [x, y, z, w], body FRD -> world NED (normalised, signs made continuous).
    """

    name: str
    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=np.float64)
        position = np.asarray(self.position, dtype=np.float64)
        quaternion = np.asarray(self.quaternion, dtype=np.float64)
        if t.ndim != 1 or t.size < 2 or position.shape != (t.size, 3) or quaternion.shape != (t.size, 4):
            raise LivoxVizError(f"trajectory {self.name}: {t.size} poses; allowed: at least 2, each t, x, y, z, "
                                "qx, qy, qz, qw")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(position)) and np.all(np.isfinite(quaternion))):
            raise LivoxVizError(f"trajectory {self.name}: NaN or infinite values; allowed: finite numbers")
        if np.any(np.diff(t) <= 0):
            row = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
            raise LivoxVizError(f"trajectory {self.name}: time goes back or repeats at pose {row + 1} "
                                f"(t = {t[row]:g} s); allowed: strictly increasing times")
        norm = np.linalg.norm(quaternion, axis=1)
        if np.any(np.abs(norm - 1.0) > 0.1):
            row = int(np.flatnonzero(np.abs(norm - 1.0) > 0.1)[0])
            raise LivoxVizError(f"trajectory {self.name}: the quaternion of pose {row + 1} has length "
                                f"{norm[row]:.3g}; allowed: a unit quaternion qx qy qz qw")
        quaternion = quaternion / norm[:, None]
        # q and -q are the same rotation: make neighbours agree so slerp takes the short way.
        flips = np.cumsum(np.concatenate([[0], np.einsum("ij,ij->i", quaternion[1:], quaternion[:-1]) < 0])) % 2
        quaternion = np.where(flips[:, None] == 1, -quaternion, quaternion)
        relative = quat_multiply(quat_conjugate(quaternion[:-1]), quaternion[1:])
        angle = 2.0 * np.arctan2(np.linalg.norm(relative[:, :3], axis=1), np.abs(relative[:, 3]))
        sign = np.where(relative[:, 3] < 0, -1.0, 1.0)
        axis = relative[:, :3] * sign[:, None]
        length = np.linalg.norm(axis, axis=1)
        axis = np.divide(axis, length[:, None], out=np.zeros_like(axis), where=length[:, None] > 0)
        for name, value in (("t", t), ("position", position), ("quaternion", quaternion)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "_axis", axis)
        object.__setattr__(self, "_half_angle", 0.5 * angle)
        # Per segment: the velocity, the half-angle's rate, and the sine part A of the slerp
        # q0 (u sin h, cos h) = A sin h + q0 cos h, with A = q0 (u, 0).
        dt = np.diff(t)
        object.__setattr__(self, "_half_angle_rate", 0.5 * angle / dt)
        axis_quaternion = np.column_stack([axis, np.zeros(len(axis))])
        sine_part = quat_multiply(quaternion[:-1], axis_quaternion)
        for name, table in (("_velocity_by_axis", np.diff(position, axis=0) / dt[:, None]),
                            ("_position_by_axis", position[:-1]), ("_sine_part_by_axis", sine_part),
                            ("_quaternion_by_axis", quaternion[:-1])):
            object.__setattr__(self, name, np.ascontiguousarray(table.T))

    @property
    def span(self) -> tuple[float, float]:
        """First and last time, seconds."""
        return float(self.t[0]), float(self.t[-1])

    def check_covers(self, start: float, stop: float) -> None:
        """Refuse a scan from ``start`` to ``stop`` seconds that leaves the trajectory's span."""
        low, high = self.span
        if start < low - 1e-9 or stop > high + 1e-9:
            raise LivoxVizError(f"trajectory {self.name} spans {low:g} to {high:g} s; the scan needs {start:g} to "
                                f"{stop:g} s (no extrapolation: give a longer trajectory or fewer --seconds)")

    def poses_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Position ``(m, 3)`` and orientation ``(m, 4)`` at times ``t`` ``(m,)`` seconds (linear, slerp).

        Within segment k the slerp is ``q_k (u_k sin h, cos h)`` with h linear in t, so the result is
        ``A_k sin h + q_k cos h`` with a constant ``A_k`` per segment: two row gathers and two products
        per point, however the quaternions are written.
        """
        t = np.asarray(t, dtype=np.float64)
        if t.size == 0:
            return np.zeros((0, 3)), np.zeros((0, 4))
        sorted_times = t.size < 2 or bool(t[-1] >= t[0] and np.all(t[1:] >= t[:-1]))
        self.check_covers(*((float(t[0]), float(t[-1])) if sorted_times else (float(t.min()), float(t.max()))))
        segment = self._segments(t, sorted_times)
        elapsed = t - self.t[segment]
        # Component by component (rows of the transposed tables): long loops, where numpy is fast.
        position = np.take(self._velocity_by_axis, segment, axis=1)
        position *= elapsed
        position += np.take(self._position_by_axis, segment, axis=1)
        half = elapsed * self._half_angle_rate[segment]
        quaternion = np.take(self._sine_part_by_axis, segment, axis=1)
        quaternion *= np.sin(half)
        cosine = np.take(self._quaternion_by_axis, segment, axis=1)
        cosine *= np.cos(half)
        quaternion += cosine
        return np.ascontiguousarray(position.T), np.ascontiguousarray(quaternion.T)

    def _segments(self, t: np.ndarray, sorted_times: bool) -> np.ndarray:
        """``(m,)`` int64 the segment (pose k to k+1) of each time; fast for sorted times (one run per segment)."""
        if t.size > 64 and sorted_times:
            first = max(int(np.searchsorted(self.t, t[0], side="right")) - 1, 0)
            last = min(int(np.searchsorted(self.t, t[-1], side="right")), self.t.size - 1)
            edges = np.searchsorted(t, self.t[first + 1 : last], side="left")
            counts = np.diff(np.concatenate([[0], edges, [t.size]]))
            return np.repeat(np.arange(first, first + counts.size), counts)
        return np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, self.t.size - 2)

    def pose_at(self, t: float) -> Pose:
        """The :class:`Pose` at one time (in plain floats: it is asked for twice a frame)."""
        self.check_covers(t, t)
        k = min(max(int(np.searchsorted(self.t, t, side="right")) - 1, 0), self.t.size - 2)
        t0, t1 = float(self.t[k]), float(self.t[k + 1])
        fraction = (t - t0) / (t1 - t0)
        half = fraction * float(self._half_angle[k])
        s = math.sin(half)
        bx, by, bz = (float(v) * s for v in self._axis[k])
        bw = math.cos(half)
        ax, ay, az, aw = (float(v) for v in self.quaternion[k])
        x = aw * bx + ax * bw + ay * bz - az * by
        y = aw * by - ax * bz + ay * bw + az * bx
        z = aw * bz + ax * by - ay * bx + az * bw
        w = aw * bw - ax * bx - ay * by - az * bz
        p0, p1 = self.position[k], self.position[k + 1]
        position = tuple(float(a) + fraction * (float(b) - float(a)) for a, b in zip(p0, p1, strict=True))
        # Z-Y-X Euler angles of the quaternion (the convention of poses.euler_matrix).
        roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
        pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
        yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        return Pose(position, roll, pitch, yaw)

    def between(self, start: float, stop: float) -> Trajectory:
        """The poses from the last one at or before ``start`` to the first one at or after ``stop``."""
        first = max(int(np.searchsorted(self.t, start, side="right")) - 1, 0)
        last = min(int(np.searchsorted(self.t, stop, side="left")) + 1, self.t.size)
        last = max(last, first + 2)
        return Trajectory(self.name, self.t[first:last], self.position[first:last], self.quaternion[first:last])
