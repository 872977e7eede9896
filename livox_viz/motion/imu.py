"""A synthetic IMU on the vehicle: angular velocity and specific force in the body FRD frame, from a trajectory.

The trajectory is made smooth for differentiation: positions by a cubic spline
(``scipy.interpolate.CubicSpline``), orientations by a rotation spline
(``scipy.spatial.transform.RotationSpline``, whose angular rate is in the
body frame). Specific force is what an accelerometer reads:
``f = R^T (a - g)`` with ``g = (0, 0, +9.80665)`` m/s^2 in the NED world, so a
vehicle at rest reads ``(0, 0, -g)`` on its z-down axis.

Noise follows Kalibr's IMU model (the four numbers of its ``imu.yaml``): white
noise of density ``sigma`` (rad/s/sqrt(Hz), m/s^2/sqrt(Hz)) becomes
``sigma / sqrt(dt)`` per sample, and a bias random walk of density ``sigma_b``
steps by ``sigma_b * sqrt(dt)`` per sample, from one seeded generator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from livox_viz.core.errors import LivoxVizError
from livox_viz.motion.trajectory import Trajectory

GRAVITY = 9.80665
MIN_RATE = 200.0


@dataclass(frozen=True)
class ImuNoise:
    """Kalibr's IMU noise parameters (all 0: a perfect IMU).

    Parameters
    ----------
    gyroscope_noise_density : float
        rad/s/sqrt(Hz).
    gyroscope_random_walk : float
        rad/s^2/sqrt(Hz).
    accelerometer_noise_density : float
        m/s^2/sqrt(Hz).
    accelerometer_random_walk : float
        m/s^3/sqrt(Hz).
    """

    gyroscope_noise_density: float = 0.0
    gyroscope_random_walk: float = 0.0
    accelerometer_noise_density: float = 0.0
    accelerometer_random_walk: float = 0.0

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not (math.isfinite(value) and value >= 0):
                raise LivoxVizError(f"IMU {name} = {value!r}; allowed: a number >= 0")


@dataclass(frozen=True)
class ImuSamples:
    """IMU samples in the vehicle body FRD frame.

    Parameters
    ----------
    t : (n,) float64
        Seconds from the scan start.
    angular_velocity : (n, 3) float64
        rad/s, body FRD.
    specific_force : (n, 3) float64
        m/s^2, body FRD (gravity included: (0, 0, -9.81) at rest, level).
    """

    t: np.ndarray
    angular_velocity: np.ndarray
    specific_force: np.ndarray


class _Splines:
    """Cubic position and rotation splines through a (short) trajectory."""

    def __init__(self, trajectory: Trajectory) -> None:
        from scipy.interpolate import CubicSpline
        from scipy.spatial.transform import Rotation, RotationSpline

        self.position = CubicSpline(trajectory.t, trajectory.position, axis=0)
        self.rotation = RotationSpline(trajectory.t, Rotation.from_quat(trajectory.quaternion))


class TrajectoryMotion:
    """Smooth position, velocity, acceleration, orientation and body angular rate of a trajectory.

    The splines are made over windows of :attr:`WINDOW` seconds (with :attr:`MARGIN` seconds of
    poses on each side, so the window's ends do not show), one window at a time: memory stays flat
    however long the flight.

    Parameters
    ----------
    trajectory : Trajectory
    """

    WINDOW = 10.0
    MARGIN = 1.0

    def __init__(self, trajectory: Trajectory) -> None:
        self.trajectory = trajectory
        self._window = -1
        self._splines: _Splines | None = None

    def _evaluate(self, t: np.ndarray, what):
        """``what(splines, times)`` evaluated window by window over ``t``, in the order of ``t``."""
        t = np.asarray(t, dtype=np.float64)
        start = self.trajectory.span[0]
        window = np.floor((t - start) / self.WINDOW).astype(np.int64)
        results, order = [], []
        for index in np.unique(window):
            rows = np.flatnonzero(window == index)
            if index != self._window:
                low = start + index * self.WINDOW
                self._splines = _Splines(self.trajectory.between(low - self.MARGIN, low + self.WINDOW + self.MARGIN))
                self._window = int(index)
            results.append(what(self._splines, t[rows]))
            order.append(rows)
        if len(results) == 1:
            return results[0]
        stacked = np.concatenate(results)
        out = np.empty_like(stacked)
        out[np.concatenate(order)] = stacked
        return out

    def position(self, t: np.ndarray) -> np.ndarray:
        """``(n, 3)`` world NED, metres."""
        return self._evaluate(t, lambda s, x: s.position(x))

    def velocity(self, t: np.ndarray) -> np.ndarray:
        """``(n, 3)`` world NED, m/s."""
        return self._evaluate(t, lambda s, x: s.position(x, 1))

    def acceleration(self, t: np.ndarray) -> np.ndarray:
        """``(n, 3)`` world NED, m/s^2."""
        return self._evaluate(t, lambda s, x: s.position(x, 2))

    def rotation(self, t: np.ndarray):
        """The body -> world orientation at ``t``, a scipy ``Rotation`` of n."""
        from scipy.spatial.transform import Rotation

        return Rotation.from_quat(self._evaluate(t, lambda s, x: s.rotation(x).as_quat()))

    def angular_velocity(self, t: np.ndarray) -> np.ndarray:
        """``(n, 3)`` rad/s in the body frame."""
        return self._evaluate(t, lambda s, x: s.rotation(x, 1))


def synthesize_imu(trajectory: Trajectory, rate: float = MIN_RATE, noise: ImuNoise | None = None,
                   seed: int = 0, start: float | None = None, stop: float | None = None) -> ImuSamples:
    """IMU samples at ``rate`` Hz over the trajectory (or ``start`` .. ``stop`` seconds).

    Parameters
    ----------
    trajectory : Trajectory
    rate : float
        Samples per second, at least 200.
    noise : ImuNoise, optional
        Default a perfect IMU.
    seed : int
        Of the noise.
    start, stop : float, optional
        Seconds; default the trajectory's span.
    """
    if not (math.isfinite(rate) and MIN_RATE <= rate <= 10_000):
        raise LivoxVizError(f"IMU rate {rate!r} Hz; allowed: {MIN_RATE:g} to 10000")
    low, high = trajectory.span
    start = low if start is None else start
    stop = high if stop is None else stop
    trajectory.check_covers(start, stop)
    t = start + np.arange(math.floor((stop - start) * rate + 1e-9) + 1) / rate
    motion = TrajectoryMotion(trajectory)
    gravity = np.array([0.0, 0.0, GRAVITY])
    force = motion.rotation(t).inv().apply(motion.acceleration(t) - gravity)
    omega = motion.angular_velocity(t)  # the splines are made one window at a time
    noise = noise or ImuNoise()
    if any(vars(noise).values()):
        rng = np.random.default_rng(seed)
        dt = 1.0 / rate
        omega = omega + _noisy(rng, t.size, noise.gyroscope_noise_density, noise.gyroscope_random_walk, dt)
        force = force + _noisy(rng, t.size, noise.accelerometer_noise_density, noise.accelerometer_random_walk, dt)
    return ImuSamples(t, omega, force)


def _noisy(rng: np.random.Generator, count: int, density: float, walk: float, dt: float) -> np.ndarray:
    """``(count, 3)`` white noise plus a bias random walk (starting at 0), Kalibr's discrete model."""
    white = rng.standard_normal((count, 3)) * (density / math.sqrt(dt))
    bias = np.cumsum(rng.standard_normal((count, 3)) * (walk * math.sqrt(dt)), axis=0)
    return white + bias
