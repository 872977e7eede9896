"""A synthetic IMU on the vehicle: the derivatives of the one motion model, in the body or the lidar frame.

The readings come from the trajectory's C2 model (:mod:`~livox_viz.motion.trajectory`),
the same one the rays, the frame poses, ``/odom`` and ``/tf`` use:

* angular rate: the model's body angular velocity ``omega`` (rad/s);
* specific force: what an accelerometer reads, ``f = R^T (a - g)`` with
  ``g = (0, 0, +9.80665)`` m/s^2 in the NED world, so a vehicle at rest reads
  ``(0, 0, -g)`` on its z-down axis.

**Where the IMU sits.** By default at the vehicle's body origin, axes body FRD
(``base_link`` in the bag). With ``mount`` (the lidar's pose on the vehicle) it
sits at the lidar's origin with the lidar's axes, as the Livox driver publishes
its built-in IMU in ``livox_frame``: ``omega_s = R_m^T omega`` and
``f_s = R_m^T (f + alpha x m + omega x (omega x m))`` with ``m`` the lever arm
and ``alpha`` the body angular acceleration: exact for a rigid body (the
sensor's own offset between its IMU chip and its optical centre, a few
centimetres, is not modelled).

Noise follows Kalibr's IMU model (the four numbers of its ``imu.yaml``): white
noise of density ``sigma`` (rad/s/sqrt(Hz), m/s^2/sqrt(Hz)) becomes
``sigma / sqrt(dt)`` per sample, and a bias random walk of density ``sigma_b``
steps by ``sigma_b * sqrt(dt)`` per sample, from one seeded generator.
:class:`ImuStream` makes the samples a stretch at a time (memory stays flat
over a long flight); the bias carries over between stretches.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from livox_viz.core.errors import LivoxVizError, quoted
from livox_viz.core.poses import Pose
from livox_viz.motion.trajectory import Trajectory

#: Where an IMU sits: the vehicle's body origin and axes (``base_link``) or the lidar's (``livox_frame``).
IMU_FRAMES: tuple[str, ...] = ("body", "lidar")

GRAVITY = 9.80665
MIN_RATE = 200.0
MAX_RATE = 10_000.0
#: The largest gyroscope noise numbers allowed (rad/s/sqrt(Hz), rad/s^2/sqrt(Hz)): 100x a consumer MEMS part's.
MAX_GYROSCOPE_NOISE = 1.0
#: The largest accelerometer noise numbers allowed (m/s^2/sqrt(Hz), m/s^3/sqrt(Hz)).
MAX_ACCELEROMETER_NOISE = 10.0


@dataclass(frozen=True)
class ImuNoise:
    """Kalibr's IMU noise parameters (all 0: a perfect IMU).

    Parameters
    ----------
    gyroscope_noise_density : float
        rad/s/sqrt(Hz), 0 to 1.
    gyroscope_random_walk : float
        rad/s^2/sqrt(Hz), 0 to 1.
    accelerometer_noise_density : float
        m/s^2/sqrt(Hz), 0 to 10.
    accelerometer_random_walk : float
        m/s^3/sqrt(Hz), 0 to 10.
    """

    gyroscope_noise_density: float = 0.0
    gyroscope_random_walk: float = 0.0
    accelerometer_noise_density: float = 0.0
    accelerometer_random_walk: float = 0.0

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            high = MAX_GYROSCOPE_NOISE if name.startswith("gyroscope") else MAX_ACCELEROMETER_NOISE
            if not (math.isfinite(value) and 0 <= value <= high):
                raise LivoxVizError(f"IMU {name} = {quoted(value)}; allowed: 0 to {high:g}")

    def sample_variances(self, rate: float) -> tuple[float, float]:
        """The white noise's variance per sample at ``rate`` Hz: gyroscope (rad/s)^2, accelerometer (m/s^2)^2
        (``(density * sqrt(rate))^2``, what an IMU message's covariance states; the bias walk is not in it)."""
        return self.gyroscope_noise_density**2 * rate, self.accelerometer_noise_density**2 * rate


@dataclass(frozen=True)
class ImuSamples:
    """IMU samples in the IMU's frame (body FRD, or the lidar's FRD with a mount).

    Parameters
    ----------
    t : (n,) float64
        Seconds from the scan start.
    angular_velocity : (n, 3) float64
        rad/s.
    specific_force : (n, 3) float64
        m/s^2 (gravity included: (0, 0, -9.81) at rest, level).
    """

    t: np.ndarray
    angular_velocity: np.ndarray
    specific_force: np.ndarray


def imu_readings(trajectory: Trajectory, t: np.ndarray, mount: Pose | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Perfect angular rate ``(n, 3)`` rad/s and specific force ``(n, 3)`` m/s^2 at times ``t`` ``(n,)``.

    In the body FRD frame at the body origin, or with ``mount`` in the lidar's frame at its origin.
    """
    gravity = np.array([0.0, 0.0, GRAVITY])
    force = trajectory.rotation_at(t).inv().apply(trajectory.acceleration_at(t) - gravity)
    omega = trajectory.angular_velocity_at(t)
    if mount is not None:
        lever = mount.origin
        alpha = trajectory.angular_acceleration_at(t)
        force = force + np.cross(alpha, lever) + np.cross(omega, np.cross(omega, lever))
        force = force @ mount.rotation  # R_m^T f, row by row
        omega = omega @ mount.rotation
    return omega, force


class ImuStream:
    """IMU samples at ``rate`` Hz from ``start`` on, a stretch at a time.

    Parameters
    ----------
    trajectory : Trajectory
    rate : float
        Samples per second, 200 to 10000.
    noise : ImuNoise, optional
        Default a perfect IMU.
    seed : int
        Of the noise.
    start : float
        Time of the first sample, seconds.
    mount : Pose, optional
        Put the IMU at the lidar's origin with its axes (see the module docstring).
    """

    def __init__(self, trajectory: Trajectory, rate: float = MIN_RATE, noise: ImuNoise | None = None,
                 seed: int = 0, start: float = 0.0, mount: Pose | None = None) -> None:
        if not (math.isfinite(rate) and MIN_RATE <= rate <= MAX_RATE):
            raise LivoxVizError(f"IMU rate {quoted(rate)} Hz; allowed: {MIN_RATE:g} to {MAX_RATE:g}")
        self.trajectory = trajectory
        self.rate = rate
        self.noise = noise or ImuNoise()
        self.start = start
        self.mount = mount
        self._next = 0
        self._rng = np.random.default_rng(seed)
        self._bias = np.zeros((2, 3))

    @property
    def time(self) -> float:
        """Time of the next sample, seconds."""
        return self.start + self._next / self.rate

    def until(self, stop: float, inclusive: bool = False) -> ImuSamples:
        """The next samples before ``stop`` seconds (and at it, with ``inclusive``)."""
        last = (stop - self.start) * self.rate
        # Sample j is at start + j / rate; the tolerance keeps a stop computed as j / rate on sample j.
        upto = math.floor(last + 1e-9) + 1 if inclusive else math.ceil(last - 1e-9)
        upto = max(upto, self._next)
        t = self.start + np.arange(self._next, upto) / self.rate
        self._next = upto
        omega, force = imu_readings(self.trajectory, t, self.mount) if t.size else (np.zeros((0, 3)),) * 2
        if t.size and any(vars(self.noise).values()):
            dt = 1.0 / self.rate
            omega = omega + self._noisy(0, self.noise.gyroscope_noise_density, self.noise.gyroscope_random_walk,
                                        t.size, dt)
            force = force + self._noisy(1, self.noise.accelerometer_noise_density,
                                        self.noise.accelerometer_random_walk, t.size, dt)
        return ImuSamples(t, omega, force)

    def _noisy(self, sensor: int, density: float, walk: float, count: int, dt: float) -> np.ndarray:
        """``(count, 3)`` white noise plus the bias random walk (carried over), Kalibr's discrete model."""
        white = self._rng.standard_normal((count, 3)) * (density / math.sqrt(dt))
        bias = self._bias[sensor] + np.cumsum(self._rng.standard_normal((count, 3)) * (walk * math.sqrt(dt)), axis=0)
        self._bias[sensor] = bias[-1]
        return white + bias


def synthesize_imu(trajectory: Trajectory, rate: float = MIN_RATE, noise: ImuNoise | None = None,
                   seed: int = 0, start: float | None = None, stop: float | None = None,
                   mount: Pose | None = None) -> ImuSamples:
    """IMU samples at ``rate`` Hz from ``start`` to ``stop`` seconds (default the trajectory's span), both included.

    Parameters
    ----------
    trajectory : Trajectory
    rate : float
        Samples per second, 200 to 10000.
    noise : ImuNoise, optional
        Default a perfect IMU.
    seed : int
        Of the noise.
    start, stop : float, optional
        Seconds.
    mount : Pose, optional
        The IMU at the lidar's origin with its axes (see the module docstring).
    """
    low, high = trajectory.span
    start = low if start is None else start
    stop = high if stop is None else stop
    trajectory.check_covers(start, stop)
    return ImuStream(trajectory, rate, noise, seed, start, mount).until(stop, inclusive=True)
