"""The vehicle's motion: one C2 trajectory through the user's poses for the rays, frame poses, /odom, /tf and IMU.

A trajectory is a time series of vehicle poses (body FRD in world NED, metres;
orientation as a unit quaternion ``[qx, qy, qz, qw]`` rotating body vectors into
the world), t in seconds from the scan start: a dense TUM file from a real flight,
a sparse hand-written one, or a built-in flight sampled at 100 Hz.

**The motion model** (the one every consumer evaluates):

* Position: the natural cubic spline through the poses (C2: position, velocity and
  acceleration continuous everywhere, zero acceleration at the two ends). Per
  component, the moments solve a tridiagonal system once (``scipy.linalg.solve_banded``).
* Orientation: the same natural cubic spline through the four quaternion
  components (signs made continuous), normalised: ``q(t) = p(t) / |p(t)|``. It
  passes through every pose, is C2 wherever ``p`` is not zero (the constructor
  refuses neighbouring poses more than 120 degrees apart, or a spline that dips
  below half length between them), and its body angular rate is
  ``omega = 2 vec(p* p') / |p|^2``, its angular acceleration
  ``2 vec(p* p'') / |p|^2 - omega 2 (p . p') / |p|^2``: both continuous, so an IMU
  sees no step at a pose or anywhere else.
* Storage: per segment, the power coefficients of the seven components in the
  time since the segment's start, ``(n - 1, 4, 7)`` float64 (224 bytes a pose).
  Nothing else: a flight's memory is its poses', evaluation is local
  (a segment lookup and Horner), and the result does not depend on how a scan
  is cut into chunks. A spline's dependence on a distant pose decays by at least
  half per pose (diagonal dominance), so the poses 64 beyond a window of a long
  file change nothing inside it (2^-64): :func:`~livox_viz.motion.tum.load_tum`
  reads only the scan's span plus that margin.

Per-ray poses evaluate this model exactly, in a compiled kernel
(:mod:`~livox_viz.motion.track`); frame poses, ``/odom``, ``/tf`` and the IMU use
the numpy evaluation here. Sources: :mod:`~livox_viz.motion.tum`,
:mod:`~livox_viz.motion.flights`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from livox_viz.core.errors import LivoxVizError
from livox_viz.core.poses import MAX_POSITION_M, Pose, pose_from_quaternion
from livox_viz.core.rotations import quat_conjugate_product_vector

#: Neighbouring orientations at most this far apart, degrees (beyond it the turn's direction is a guess).
MAX_TURN_DEG = 120.0
#: The orientation spline ``p`` must keep at least this length between poses (normalising divides by it).
MIN_QUATERNION_LENGTH = 0.5
#: Poses at least this far apart, seconds: with positions within 1e7 m, the spline's slopes stay far from overflow
#: (1e-300 s apart gave NaN poses and numpy's overflow warnings).
MIN_POSE_STEP_S = 1e-6
#: Times within this of the scan start, seconds (about 300 years: a Unix date is read, then refused as outside the
#: scan, by :meth:`Trajectory.check_covers`).
MAX_TIME_S = 1e10
#: Rows evaluated at once by the numpy evaluation (bounds its temporaries).
_EVALUATION_BLOCK = 1 << 16
#: Times whose last evaluation :meth:`Trajectory._components` keeps (a frame's IMU samples, at 10 kHz too).
_KEPT_TIMES = 4096


def natural_spline_coefficients(t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Power coefficients of the natural cubic spline through ``values`` at ``t``.

    Parameters
    ----------
    t : (n,) float64
        Knots, strictly increasing, n >= 2.
    values : (n, k) float64
        k components.

    Returns
    -------
    coefficients : (n - 1, 4, k) float64
        Segment i is ``c0 + c1 u + c2 u^2 + c3 u^3`` with ``u = t - t[i]``.
    """
    from scipy.linalg import solve_banded

    n = t.size
    h = np.diff(t)
    slope = np.diff(values, axis=0) / h[:, None]
    moments = np.zeros_like(values)
    if n > 2:
        bands = np.zeros((3, n - 2))
        bands[0, 1:] = h[1:-1]
        bands[1] = 2.0 * (h[:-1] + h[1:])
        bands[2, :-1] = h[1:-1]
        moments[1:-1] = solve_banded((1, 1), bands, 6.0 * np.diff(slope, axis=0), check_finite=False)
    coefficients = np.empty((n - 1, 4, values.shape[1]))
    coefficients[:, 0] = values[:-1]
    coefficients[:, 1] = slope - h[:, None] * (2.0 * moments[:-1] + moments[1:]) / 6.0
    coefficients[:, 2] = 0.5 * moments[:-1]
    coefficients[:, 3] = (moments[1:] - moments[:-1]) / (6.0 * h[:, None])
    return coefficients


@dataclass(frozen=True)
class Trajectory:
    """Vehicle poses over time and the C2 motion through them (see the module docstring).

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
        far = np.abs(position).max(axis=1) > MAX_POSITION_M
        if far.any():
            row = int(np.argmax(far))
            raise LivoxVizError(f"trajectory {self.name}: pose {row + 1} (t = {t[row]:g} s) is at "
                                f"{', '.join(f'{v:.4g}' for v in position[row])} m; allowed: |x|, |y|, |z| <= "
                                f"{MAX_POSITION_M:g} m (a local NED frame), as --pose")
        if not np.all(np.abs(t) <= MAX_TIME_S):
            row = int(np.argmax(np.abs(t) > MAX_TIME_S))
            raise LivoxVizError(f"trajectory {self.name}: pose {row + 1} is at t = {t[row]:g} s; allowed: times within "
                                f"{MAX_TIME_S:g} s of the scan start (seconds from it, not dates)")
        if np.any(np.diff(t) <= 0):
            row = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
            raise LivoxVizError(f"trajectory {self.name}: time goes back or repeats at pose {row + 1} "
                                f"(t = {t[row]:g} s); allowed: strictly increasing times")
        if np.any(np.diff(t) < MIN_POSE_STEP_S):  # closer poses made the spline's slopes overflow (NaN poses)
            row = int(np.argmax(np.diff(t) < MIN_POSE_STEP_S))
            raise LivoxVizError(f"trajectory {self.name}: poses {row + 1} and {row + 2} are {t[row + 1] - t[row]:.3g} "
                                f"s apart (t = {t[row]:.9g} s); allowed: at least {MIN_POSE_STEP_S:g} s between poses")
        norm = np.linalg.norm(quaternion, axis=1)
        if np.any(np.abs(norm - 1.0) > 0.1):
            row = int(np.flatnonzero(np.abs(norm - 1.0) > 0.1)[0])
            raise LivoxVizError(f"trajectory {self.name}: the quaternion of pose {row + 1} has length "
                                f"{norm[row]:.3g}; allowed: a unit quaternion qx qy qz qw")
        quaternion = quaternion / norm[:, None]
        # q and -q are the same rotation: make neighbours agree so the spline takes the short way.
        flips = np.cumsum(np.concatenate([[0], np.einsum("ij,ij->i", quaternion[1:], quaternion[:-1]) < 0])) % 2
        quaternion = np.where(flips[:, None] == 1, -quaternion, quaternion)
        cosine = np.clip(np.einsum("ij,ij->i", quaternion[1:], quaternion[:-1]), -1.0, 1.0)
        turn = np.degrees(2.0 * np.arccos(cosine))
        if np.any(turn > MAX_TURN_DEG):
            row = int(np.argmax(turn > MAX_TURN_DEG))
            raise LivoxVizError(f"trajectory {self.name}: the orientation turns {turn[row]:.0f} degrees between poses "
                                f"{row + 1} and {row + 2} (t = {t[row]:g} to {t[row + 1]:g} s); allowed: at most "
                                f"{MAX_TURN_DEG:g} between neighbours (add poses in between)")
        coefficients = natural_spline_coefficients(t, np.hstack([position, quaternion]))
        # The orientation spline between poses must stay well away from zero length (checked mid-segment).
        u = 0.5 * np.diff(t)[:, None]
        c = coefficients[:, :, 3:]
        shortest = np.linalg.norm(c[:, 0] + u * (c[:, 1] + u * (c[:, 2] + u * c[:, 3])), axis=1)
        if np.any(shortest < MIN_QUATERNION_LENGTH):
            row = int(np.argmax(shortest < MIN_QUATERNION_LENGTH))
            raise LivoxVizError(f"trajectory {self.name}: the orientation swings too far between poses {row + 1} and "
                                f"{row + 2} (t = {t[row]:g} to {t[row + 1]:g} s) to interpolate; add poses in between")
        for name, value in (("t", t), ("position", position), ("quaternion", quaternion),
                            ("coefficients", coefficients)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    # Span -------------------------------------------------------------------------------------
    @property
    def span(self) -> tuple[float, float]:
        """First and last time, seconds."""
        return float(self.t[0]), float(self.t[-1])

    @property
    def moves(self) -> bool:
        """Whether the vehicle moves or turns at all along the trajectory."""
        return bool(np.ptp(self.position, axis=0).max() > 0 or np.ptp(self.quaternion, axis=0).max() > 0)

    def check_covers(self, start: float, stop: float) -> None:
        """Refuse a scan from ``start`` to ``stop`` seconds that leaves the trajectory's span."""
        low, high = self.span
        if start < low - 1e-9 or stop > high + 1e-9:
            raise LivoxVizError(f"trajectory {self.name} spans {low:g} to {high:g} s; the scan needs {start:g} to "
                                f"{stop:g} s (no extrapolation: give a longer trajectory or fewer --seconds)")

    def _times(self, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        if t.size:
            self.check_covers(float(t.min()), float(t.max()))
        return t

    # Evaluation -------------------------------------------------------------------------------
    def _components(self, t: np.ndarray, order: int) -> np.ndarray:
        """``(m, 7)`` derivative ``order`` (0..2) of the seven spline components at ``t``.

        A bag's frame asks for the same times several times (its IMU samples' rotation, acceleration and rate,
        then their ground truth's position, rotation, velocity and rate: nine evaluations of three orders): the
        last times' values are kept, a stretch at a time (at most :data:`_KEPT_TIMES` times).
        """
        times = t.tobytes() if t.size <= _KEPT_TIMES else None
        kept = self.__dict__.get(f"_kept{order}")
        if times is not None and kept is not None and kept[0] == times:
            return kept[1].copy()
        out = self._evaluate(t, order)
        if times is not None:
            self.__dict__[f"_kept{order}"] = (times, out.copy())  # one assignment: a thread reads old or new whole
        return out

    def _evaluate(self, t: np.ndarray, order: int) -> np.ndarray:
        out = np.empty((t.size, 7))
        for first in range(0, t.size, _EVALUATION_BLOCK):
            block = t[first : first + _EVALUATION_BLOCK]
            segment = np.clip(np.searchsorted(self.t, block, side="right") - 1, 0, self.t.size - 2)
            u = (block - self.t[segment])[:, None]
            c = self.coefficients[segment]
            if order == 0:
                value = c[:, 0] + u * (c[:, 1] + u * (c[:, 2] + u * c[:, 3]))
            elif order == 1:
                value = c[:, 1] + u * (2.0 * c[:, 2] + u * 3.0 * c[:, 3])
            else:
                value = 2.0 * c[:, 2] + 6.0 * u * c[:, 3]
            out[first : first + block.size] = value
        return out

    def position_at(self, t) -> np.ndarray:
        """``(m, 3)`` world NED, metres, at times ``t`` ``(m,)`` seconds."""
        return self._components(self._times(t), 0)[:, :3]

    def velocity_at(self, t) -> np.ndarray:
        """``(m, 3)`` world NED, m/s."""
        return self._components(self._times(t), 1)[:, :3]

    def acceleration_at(self, t) -> np.ndarray:
        """``(m, 3)`` world NED, m/s^2."""
        return self._components(self._times(t), 2)[:, :3]

    def orientation_at(self, t) -> np.ndarray:
        """``(m, 4)`` unit quaternions [x, y, z, w], body FRD -> world NED."""
        p = self._components(self._times(t), 0)[:, 3:]
        return p / np.linalg.norm(p, axis=1, keepdims=True)

    def rotation_at(self, t):
        """The body -> world orientation at ``t``, a scipy ``Rotation`` of m."""
        from scipy.spatial.transform import Rotation

        return Rotation.from_quat(self.orientation_at(t))

    def angular_velocity_at(self, t) -> np.ndarray:
        """``(m, 3)`` rad/s in the body FRD frame: ``2 vec(p* p') / |p|^2``."""
        t = self._times(t)
        p, dp = self._components(t, 0)[:, 3:], self._components(t, 1)[:, 3:]
        return 2.0 * quat_conjugate_product_vector(p, dp) / np.einsum("ij,ij->i", p, p)[:, None]

    def angular_acceleration_at(self, t) -> np.ndarray:
        """``(m, 3)`` rad/s^2 in the body FRD frame (the derivative of :meth:`angular_velocity_at`)."""
        t = self._times(t)
        p, dp, ddp = (self._components(t, k)[:, 3:] for k in range(3))
        length2 = np.einsum("ij,ij->i", p, p)[:, None]
        omega = 2.0 * quat_conjugate_product_vector(p, dp) / length2
        stretch = 2.0 * np.einsum("ij,ij->i", p, dp)[:, None] / length2
        return 2.0 * quat_conjugate_product_vector(p, ddp) / length2 - omega * stretch

    def poses_at(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Position ``(m, 3)`` and orientation ``(m, 4)`` [x, y, z, w] at times ``t`` ``(m,)`` seconds."""
        t = self._times(t)
        values = self._components(t, 0)
        return values[:, :3], values[:, 3:] / np.linalg.norm(values[:, 3:], axis=1, keepdims=True)

    def pose_at(self, t: float) -> Pose:
        """The :class:`Pose` at one time."""
        position, quaternion = self.poses_at(np.array([float(t)]))
        return pose_from_quaternion(position[0], quaternion[0])
