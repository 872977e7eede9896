"""The sensor's track: the vehicle's motion with the mount applied, evaluated for every ray.

The sensor's pose at time t is the vehicle's (:class:`~livox_viz.motion.trajectory.Trajectory`,
the one C2 motion model) composed with the fixed mount ``(m, R_m)``:

* orientation ``q_s(t) = q_v(t) q_m``: the vehicle's quaternion spline ``p(t)`` times
  the constant ``q_m`` is again a cubic per segment (its coefficients multiplied once),
  normalised by the same ``|p(t)|``;
* position ``o_s(t) = o_v(t) + R_v(t) m = o_v(t) + R_s(t) m'`` with ``m' = R_m^T m``
  the lever arm in the sensor frame.

Per ray this is evaluated exactly, not interpolated: a compiled kernel (numba,
``nogil``) finds the segment (walking forward through sorted times, a binary
search otherwise), evaluates the seven cubics by Horner, and rotates the lever arm
and the ray's sensor-frame direction with the homogeneous quaternion formula
``(w^2 - |u|^2) v + 2 (u.v) u + 2 w (u x v)`` divided by ``|p|^2`` (no
square root). About 15 ns a ray, a few percent of the ray's cast; numpy would
need some 50 passes over the rays (measured 5x slower), which is why numba is a
dependency.
"""

from __future__ import annotations

import math

import numpy as np

from livox_viz.core.poses import Pose, pose_quaternion
from livox_viz.core.rotations import quat_multiply, quat_rotate
from livox_viz.motion.trajectory import Trajectory, pose_from_quaternion


def _right_multiplier(q: np.ndarray) -> np.ndarray:
    """``(4, 4)`` M with ``p q = M @ p`` for quaternions [x, y, z, w] (right multiplication is linear)."""
    return np.stack([quat_multiply(column, q) for column in np.eye(4)], axis=1)


class SensorTrack:
    """The sensor's pose along a vehicle trajectory, at any time and for every ray.

    Parameters
    ----------
    trajectory : Trajectory
        The vehicle's motion (body FRD in world NED).
    mount : Pose
        The sensor's pose on the vehicle (FRD).
    """

    def __init__(self, trajectory: Trajectory, mount: Pose) -> None:
        self.trajectory = trajectory
        self.mount = mount
        self._mount_quaternion = pose_quaternion(mount)
        self._mount_origin = mount.origin
        coefficients = np.array(trajectory.coefficients)
        # Right-multiplying every power coefficient of p by q_m gives the coefficients of p q_m.
        coefficients[:, :, 3:] = coefficients[:, :, 3:] @ _right_multiplier(self._mount_quaternion).T
        self._coefficients = np.ascontiguousarray(coefficients)
        self._lever = np.ascontiguousarray(mount.rotation.T @ mount.origin)
        self._last_pose: tuple[float, Pose] | None = None

    @property
    def span(self) -> tuple[float, float]:
        """First and last time, seconds."""
        return self.trajectory.span

    def poses_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The sensor's position ``(m, 3)`` and orientation ``(m, 4)`` [x, y, z, w] (sensor FRD -> world NED)."""
        position, quaternion = self.trajectory.poses_at(t)
        origin = position + quat_rotate(quaternion, np.broadcast_to(self._mount_origin, position.shape))
        return origin, quat_multiply(quaternion, self._mount_quaternion)

    def pose_at(self, t: float) -> Pose:
        """The sensor's :class:`Pose` in the world at time ``t`` seconds.

        In plain floats, and the last answer kept: a frame asks for its start and its end, and the next frame
        starts where it ended.
        """
        t = float(t)
        if self._last_pose is not None and self._last_pose[0] == t:
            return self._last_pose[1]
        self.trajectory.check_covers(t, t)
        knots = self.trajectory.t
        k = min(max(int(np.searchsorted(knots, t, side="right")) - 1, 0), knots.size - 2)
        u = t - float(knots[k])
        c0, c1, c2, c3 = self._coefficients[k].tolist()
        ox, oy, oz, x, y, z, w = (a + u * (b + u * (c + u * d)) for a, b, c, d in zip(c0, c1, c2, c3, strict=True))
        length = math.sqrt(x * x + y * y + z * z + w * w)
        x, y, z, w = x / length, y / length, z / length, w / length
        # The lever arm (sensor frame) into the world: m' + 2w (u x m') + 2 u x (u x m').
        lx, ly, lz = self._lever.tolist()
        tx, ty, tz = 2 * (y * lz - z * ly), 2 * (z * lx - x * lz), 2 * (x * ly - y * lx)
        origin = (ox + lx + w * tx + (y * tz - z * ty), oy + ly + w * ty + (z * tx - x * tz),
                  oz + lz + w * tz + (x * ty - y * tx))
        pose = pose_from_quaternion(np.array(origin), np.array([x, y, z, w]))
        self._last_pose = (t, pose)
        return pose

    def rays(self, t: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each ray's origin and world direction from the sensor's pose at its own time.

        Parameters
        ----------
        t : (n,) float64
            Seconds, inside the span (fastest when sorted).
        directions : (n, 3) float64
            Unit directions, sensor FRD.

        Returns
        -------
        origins : (n, 3) float64
            World NED, metres.
        directions_world : (n, 3) float64
            Unit directions, world NED.
        """
        t = np.ascontiguousarray(t, dtype=np.float64)
        directions = np.ascontiguousarray(directions, dtype=np.float64)
        if t.size:
            self.trajectory.check_covers(float(t.min()), float(t.max()))
        origins = np.empty((t.size, 3))
        directions_world = np.empty((t.size, 3))
        _ray_kernel()(t, self.trajectory.t, self._coefficients, self._lever, directions, origins, directions_world)
        return origins, directions_world


_KERNEL = None


def _ray_kernel():
    """The compiled per-ray kernel (numba imported and the kernel compiled, or loaded from its cache, on first use)."""
    global _KERNEL
    if _KERNEL is None:
        import numba

        segments = numba.njit(cache=True, nogil=True)(_segments)
        body = numba.njit(cache=True, nogil=True, fastmath=True)(_ray_poses)

        def kernel(t, knots, coefficients, lever, directions, origins, directions_world):
            segment = np.empty(t.shape[0], dtype=np.int64)
            segments(t, knots, segment)
            body(t, knots, segment, coefficients, lever, directions, origins, directions_world)

        _KERNEL = kernel
    return _KERNEL


def _segments(t, knots, segment):  # pragma: no cover - compiled
    """``segment[i]``: the spline segment of ``t[i]`` (a walk for sorted times, a binary search otherwise)."""
    last = knots.shape[0] - 2
    k = 0
    for i in range(t.shape[0]):
        ti = t[i]
        if ti < knots[k] or (k < last and ti >= knots[k + 1]):
            if k < last and ti >= knots[k + 1] and (k + 1 == last or ti < knots[k + 2]):
                k += 1
            else:
                low, high = 0, last
                while low < high:
                    middle = (low + high + 1) // 2
                    if knots[middle] <= ti:
                        low = middle
                    else:
                        high = middle - 1
                k = low
        segment[i] = k


def _ray_poses(t, knots, segment, coefficients, lever, directions, origins, directions_world):  # pragma: no cover
    """See :meth:`SensorTrack.rays`; ``coefficients`` ``(segments, 4, 7)``: position, then the sensor's p(t).

    Compiled with ``fastmath`` (reassociation and vector instructions; no NaN or infinity can arise here: the
    times are inside the span and ``|p|`` >= 0.5).
    """
    lx, ly, lz = lever[0], lever[1], lever[2]
    for i in range(t.shape[0]):
        k = segment[i]
        u = t[i] - knots[k]
        c = coefficients[k]
        ox = c[0, 0] + u * (c[1, 0] + u * (c[2, 0] + u * c[3, 0]))
        oy = c[0, 1] + u * (c[1, 1] + u * (c[2, 1] + u * c[3, 1]))
        oz = c[0, 2] + u * (c[1, 2] + u * (c[2, 2] + u * c[3, 2]))
        qx = c[0, 3] + u * (c[1, 3] + u * (c[2, 3] + u * c[3, 3]))
        qy = c[0, 4] + u * (c[1, 4] + u * (c[2, 4] + u * c[3, 4]))
        qz = c[0, 5] + u * (c[1, 5] + u * (c[2, 5] + u * c[3, 5]))
        qw = c[0, 6] + u * (c[1, 6] + u * (c[2, 6] + u * c[3, 6]))
        vector2 = qx * qx + qy * qy + qz * qz
        inverse = 1.0 / (vector2 + qw * qw)
        scale = (qw * qw - vector2) * inverse
        twice_w = 2.0 * qw * inverse
        # The lever arm (sensor frame) into the world.
        along = 2.0 * (qx * lx + qy * ly + qz * lz) * inverse
        origins[i, 0] = ox + scale * lx + along * qx + twice_w * (qy * lz - qz * ly)
        origins[i, 1] = oy + scale * ly + along * qy + twice_w * (qz * lx - qx * lz)
        origins[i, 2] = oz + scale * lz + along * qz + twice_w * (qx * ly - qy * lx)
        vx, vy, vz = directions[i, 0], directions[i, 1], directions[i, 2]
        along = 2.0 * (qx * vx + qy * vy + qz * vz) * inverse
        directions_world[i, 0] = scale * vx + along * qx + twice_w * (qy * vz - qz * vy)
        directions_world[i, 1] = scale * vy + along * qy + twice_w * (qz * vx - qx * vz)
        directions_world[i, 2] = scale * vz + along * qz + twice_w * (qx * vy - qy * vx)
