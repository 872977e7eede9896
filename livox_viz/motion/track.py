"""The sensor's track: the vehicle's motion with the mount applied, evaluated for every ray.

The sensor's pose at time t is the vehicle's (:class:`~livox_viz.motion.trajectory.Trajectory`,
the one C2 motion model) composed with the fixed mount ``(m, R_m)``:

* orientation ``q_s(t) = q_v(t) q_m``: the vehicle's quaternion spline ``p(t)`` times
  the constant ``q_m`` is again a cubic per segment (its coefficients multiplied once),
  normalised by the same ``|p(t)|``;
* position ``o_s(t) = o_v(t) + R_v(t) m = o_v(t) + R_s(t) m'`` with ``m' = R_m^T m``
  the lever arm in the sensor frame.

Per ray this is evaluated exactly, not interpolated: a compiled kernel (numba,
``nogil``) takes the rays a segment at a time (a binary search per run of rays;
sorted times make runs of hundreds), evaluates the seven cubics by Horner, and
rotates the lever arm and the ray's sensor-frame direction with the homogeneous
quaternion formula ``(w^2 - |u|^2) v + 2 (u.v) u + 2 w (u x v)`` divided by
``|p|^2`` (no square root). About 12 ns a ray, a few percent of the ray's cast;
numpy would need some 50 passes over the rays (measured 5x slower), which is
why numba is a dependency.
"""

from __future__ import annotations

import math

import numpy as np

from livox_viz.core.compiled import LazyKernels
from livox_viz.core.poses import Pose, pose_from_quaternion, pose_quaternion
from livox_viz.core.rotations import quat_multiply, quat_right_multiplier, quat_rotate
from livox_viz.motion.trajectory import Trajectory


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
        coefficients[:, :, 3:] = coefficients[:, :, 3:] @ quat_right_multiplier(self._mount_quaternion).T
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
        last = self._last_pose  # one read: another thread may replace it
        if last is not None and last[0] == t:
            return last[1]
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

    def rays(self, t: np.ndarray, directions: np.ndarray,
             out: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Each ray's origin and world direction from the sensor's pose at its own time.

        Parameters
        ----------
        t : (n,) float64
            Seconds, inside the span (fastest when sorted).
        directions : (n, 3) float64
            Unit directions, sensor FRD.
        out : ((n, 3), (n, 3)) float64 C-contiguous, optional
            Where the origins and world directions go (new arrays by default).

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
        origins, directions_world = out if out is not None else (np.empty((t.size, 3)), np.empty((t.size, 3)))
        _KERNELS("rays")(t, self.trajectory.t, self._coefficients, self._lever, directions, origins, directions_world)
        return origins, directions_world


def _rays(t, knots, coefficients, lever, directions, origins, directions_world):  # pragma: no cover - compiled
    """See :meth:`SensorTrack.rays`; ``coefficients`` ``(segments, 4, 7)``: position, then the sensor's p(t).

    Run by run: the rays of one spline segment (a binary search finds it; sorted times make long runs) share its
    28 coefficients, so the inner loop has no gathers and vectorises. Compiled with ``fastmath``: no NaN or
    infinity can arise (the times are inside the span, ``|p|`` >= 0.5 there).
    """
    count = t.shape[0]
    last = knots.shape[0] - 2
    lx, ly, lz = lever[0], lever[1], lever[2]
    i = 0
    while i < count:
        low, high = 0, last
        while low < high:
            middle = (low + high + 1) // 2
            if knots[middle] <= t[i]:
                low = middle
            else:
                high = middle - 1
        k = low
        start = knots[k]
        end = knots[k + 1] if k < last else np.inf
        stop = i + 1
        while stop < count and start <= t[stop] < end:
            stop += 1
        c = coefficients[k]
        c00, c10, c20, c30 = c[0, 0], c[1, 0], c[2, 0], c[3, 0]
        c01, c11, c21, c31 = c[0, 1], c[1, 1], c[2, 1], c[3, 1]
        c02, c12, c22, c32 = c[0, 2], c[1, 2], c[2, 2], c[3, 2]
        c03, c13, c23, c33 = c[0, 3], c[1, 3], c[2, 3], c[3, 3]
        c04, c14, c24, c34 = c[0, 4], c[1, 4], c[2, 4], c[3, 4]
        c05, c15, c25, c35 = c[0, 5], c[1, 5], c[2, 5], c[3, 5]
        c06, c16, c26, c36 = c[0, 6], c[1, 6], c[2, 6], c[3, 6]
        for r in range(i, stop):
            u = t[r] - start
            ox = c00 + u * (c10 + u * (c20 + u * c30))
            oy = c01 + u * (c11 + u * (c21 + u * c31))
            oz = c02 + u * (c12 + u * (c22 + u * c32))
            qx = c03 + u * (c13 + u * (c23 + u * c33))
            qy = c04 + u * (c14 + u * (c24 + u * c34))
            qz = c05 + u * (c15 + u * (c25 + u * c35))
            qw = c06 + u * (c16 + u * (c26 + u * c36))
            vector2 = qx * qx + qy * qy + qz * qz
            inverse = 1.0 / (vector2 + qw * qw)
            scale = (qw * qw - vector2) * inverse
            twice_w = 2.0 * qw * inverse
            # The lever arm (sensor frame) into the world.
            along = 2.0 * (qx * lx + qy * ly + qz * lz) * inverse
            origins[r, 0] = ox + scale * lx + along * qx + twice_w * (qy * lz - qz * ly)
            origins[r, 1] = oy + scale * ly + along * qy + twice_w * (qz * lx - qx * lz)
            origins[r, 2] = oz + scale * lz + along * qz + twice_w * (qx * ly - qy * lx)
            vx, vy, vz = directions[r, 0], directions[r, 1], directions[r, 2]
            along = 2.0 * (qx * vx + qy * vy + qz * vz) * inverse
            directions_world[r, 0] = scale * vx + along * qx + twice_w * (qy * vz - qz * vy)
            directions_world[r, 1] = scale * vy + along * qy + twice_w * (qz * vx - qx * vz)
            directions_world[r, 2] = scale * vz + along * qz + twice_w * (qx * vy - qy * vx)
        i = stop


#: The compiled per-ray kernel (numba imported and the kernel compiled, or loaded from its cache, on first use).
_KERNELS = LazyKernels(globals(), options=lambda name: {"fastmath": True})
