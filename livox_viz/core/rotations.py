"""Rotations in one place: Euler angles, matrices, quaternions, and the NED/FRD <-> ENU/FLU turn.

Every frame of reference in livox-viz is built from these (scan-model.md section 5):

* World and vehicle frames are NED/FRD (z down, metres). Euler angles are
  [roll, pitch, yaw] in radians, the aerospace Z-Y-X sequence: a vector in the
  rotated (body or sensor) frame maps to the parent frame by
  ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.
* Quaternions are ``[x, y, z, w]`` (scipy's order), vectorised over leading axes;
  q rotates child-frame vectors into the parent, like R.
* ROS (REP 103/105) is ENU/FLU: world NED -> ENU is ``(y, x, -z)``, body or
  sensor FRD -> FLU is ``(x, -y, -z)``, and a rotation R (FRD -> NED) becomes
  ``C_NED_ENU R C_FRD_FLU`` (FLU -> ENU). The display's z-up view uses the same turn.
"""

from __future__ import annotations

import math

import numpy as np


def euler_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rotation from a frame with Euler angles [roll, pitch, yaw] (radians) to its parent.

    Returns
    -------
    R : (3, 3) float64
        ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``.
    """
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def matrix_to_euler(rotation: np.ndarray) -> tuple[float, float, float]:
    """The [roll, pitch, yaw] radians of a rotation built by :func:`euler_matrix`."""
    pitch = math.asin(max(-1.0, min(1.0, -float(rotation[2, 0]))))
    roll = math.atan2(float(rotation[2, 1]), float(rotation[2, 2]))
    yaw = math.atan2(float(rotation[1, 0]), float(rotation[0, 0]))
    return roll, pitch, yaw




# Quaternions [x, y, z, w], vectorised -----------------------------------------------------
def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a b`` of ``(..., 4)`` quaternions [x, y, z, w]."""
    ax, ay, az, aw = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)
    bx, by, bz, bw = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate ``(n, 3)`` vectors by ``(n, 4)`` (or ``(4,)``) unit quaternions: v + 2w (u x v) + 2 u x (u x v).

    Written on columns: a million vectors without (n, 3) temporaries of ``numpy.cross``.
    """
    q = np.asarray(q, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    x, y, z, w = (q[..., k] for k in range(4))
    vx, vy, vz = v[:, 0], v[:, 1], v[:, 2]
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    out = np.empty(v.shape)
    out[:, 0] = vx + w * tx + (y * tz - z * ty)
    out[:, 1] = vy + w * ty + (z * tx - x * tz)
    out[:, 2] = vz + w * tz + (x * ty - y * tx)
    return out


def rotate_rows(vectors: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """``(n, 3)`` vectors turned by one ``(3, 3)`` rotation, column by column.

    Not ``vectors @ rotation.T``: BLAS may round a row differently with the number of rows, and a ray's
    direction must not depend on how a scan is cut (the return model's noise and footprint follow it).
    Each output column is ``(x * R[i, 0] + y * R[i, 1]) + z * R[i, 2]`` in that order (the same rounding as
    the broadcast it replaces), over the input's columns made contiguous once: a broadcast over rows of three
    runs numpy's inner loop three values at a time, four times slower (the scan turns every ray with it).

    Parameters
    ----------
    vectors : (n, 3) float64
    rotation : (3, 3) float64

    Returns
    -------
    turned : (n, 3) float64
        ``rotation @ v`` for each row ``v``.
    """
    vectors = np.asarray(vectors, dtype=np.float64)
    rotation = np.asarray(rotation, dtype=np.float64)
    count = vectors.shape[0]
    out = np.empty((count, 3), dtype=np.float64)
    x, y, z = np.ascontiguousarray(vectors.T)
    column, term = np.empty(count), np.empty(count)
    for axis in range(3):
        np.multiply(x, rotation[axis, 0], out=column)
        column += np.multiply(y, rotation[axis, 1], out=term)
        column += np.multiply(z, rotation[axis, 2], out=term)
        out[:, axis] = column
    return out


def quat_conjugate_product_vector(p: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``(m, 3)`` the vector part of ``p* r`` for ``(m, 4)`` quaternions [x, y, z, w]."""
    u, w = p[:, :3], p[:, 3:]
    v, s = r[:, :3], r[:, 3:]
    return w * v - s * u - np.cross(u, v)


def quat_right_multiplier(q: np.ndarray) -> np.ndarray:
    """``(4, 4)`` M with ``p q = M @ p`` for quaternions [x, y, z, w] (right multiplication is linear)."""
    return np.stack([quat_multiply(column, q) for column in np.eye(4)], axis=1)


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """The inverse of unit quaternions ``(..., 4)``."""
    return np.asarray(q, dtype=np.float64) * np.array([-1.0, -1.0, -1.0, 1.0])


def quat_from_matrix(rotation: np.ndarray) -> np.ndarray:
    """``(4,)`` or ``(n, 4)`` [x, y, z, w] of a ``(3, 3)`` or ``(n, 3, 3)`` rotation matrix."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(rotation).as_quat()


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """``(..., 3, 3)`` rotation matrices of unit quaternions ``(..., 4)``."""
    x, y, z, w = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


# NED/FRD <-> ENU/FLU (REP 103/105) ---------------------------------------------------------
#: x kept, y and z negated: body or sensor FRD -> FLU, and world NED -> north-west-up (the display's z-up
#: frame). Its own inverse.
FRD_TO_FLU = np.diag([1.0, -1.0, -1.0])
#: World NED -> ENU: x and y swapped, z negated. Its own inverse.
NED_TO_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def enu_from_ned(xyz_ned: np.ndarray) -> np.ndarray:
    """``(..., 3)`` world NED -> ENU, ``(y, x, -z)``."""
    return np.asarray(xyz_ned) @ NED_TO_ENU.T


def flu_from_frd(xyz_frd: np.ndarray) -> np.ndarray:
    """``(..., 3)`` body or sensor FRD -> FLU, ``(x, -y, -z)``."""
    return np.asarray(xyz_frd) @ FRD_TO_FLU


def enu_flu_from_ned_frd(rotation_ned_frd: np.ndarray) -> np.ndarray:
    """``(3, 3)`` or ``(n, 3, 3)``: a rotation FRD -> NED as FLU -> ENU, ``C_NED_ENU R C_FRD_FLU``."""
    return NED_TO_ENU @ rotation_ned_frd @ FRD_TO_FLU
