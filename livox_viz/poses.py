"""Frames of reference: vehicle pose in the world and the sensor mount (scan-model.md section 5).

World and vehicle frames are NED/FRD (z down, metres). Euler angles are
[roll, pitch, yaw] in radians, applied as the aerospace Z-Y-X sequence: a
vector in the rotated (body or sensor) frame maps to the parent frame by
``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config import SensorConfig
from .errors import LivoxVizError


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


@dataclass(frozen=True)
class Pose:
    """A rigid pose: position in metres and [roll, pitch, yaw] in radians, in its parent's NED/FRD frame.

    Parameters
    ----------
    position : tuple of float
        x, y, z in metres (NED: north, east, down).
    roll, pitch, yaw : float
        Radians.
    """

    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0

    def __post_init__(self) -> None:
        values = [*self.position, self.roll, self.pitch, self.yaw]
        if len(self.position) != 3 or not all(math.isfinite(v) for v in values):
            raise LivoxVizError(f"pose {values!r}; allowed: 6 finite numbers x,y,z (m), roll,pitch,yaw (rad)")
        object.__setattr__(self, "position", tuple(float(v) for v in self.position))

    @property
    def rotation(self) -> np.ndarray:
        """``(3, 3)`` float64 rotation from this frame to the parent."""
        return euler_matrix(self.roll, self.pitch, self.yaw)

    @property
    def origin(self) -> np.ndarray:
        """``(3,)`` float64 position in the parent."""
        return np.array(self.position, dtype=np.float64)

    @property
    def matrix(self) -> np.ndarray:
        """``(4, 4)`` float64 homogeneous transform from this frame to the parent."""
        transform = np.eye(4)
        transform[:3, :3] = self.rotation
        transform[:3, 3] = self.origin
        return transform

    def compose(self, child: Pose) -> Pose:
        """The pose of ``child`` (given in this frame) in this frame's parent."""
        rotation = self.rotation @ child.rotation
        position = self.origin + self.rotation @ child.origin
        return Pose(tuple(position), *matrix_to_euler(rotation))

    def as_array(self) -> np.ndarray:
        """``(6,)`` float64: x, y, z, roll, pitch, yaw (RflySim's ``posAng`` order)."""
        return np.array([*self.position, self.roll, self.pitch, self.yaw], dtype=np.float64)

    @classmethod
    def parse(cls, text: str) -> Pose:
        """Parse ``"x,y,z,roll,pitch,yaw"`` (metres, radians), as given to ``--pose``."""
        parts = [p.strip() for p in text.split(",")]
        try:
            values = [float(p) for p in parts]
        except ValueError:
            raise LivoxVizError(
                f"pose {text!r} does not parse; allowed: x,y,z,roll,pitch,yaw (6 numbers, metres and radians)"
            ) from None
        if len(values) != 6:
            raise LivoxVizError(f"pose {text!r} has {len(values)} numbers; allowed: x,y,z,roll,pitch,yaw (6)")
        return cls(tuple(values[:3]), *values[3:])  # type: ignore[arg-type]


def sensor_mount(config: SensorConfig) -> Pose:
    """The sensor's pose in the vehicle body frame: ``SensorPosXYZ`` (m), ``SensorAngEuler`` (rad)."""
    return Pose(config.sensor_pos_xyz, *config.sensor_ang_euler)


def sensor_world_pose(config: SensorConfig, vehicle: Pose) -> Pose:
    """The sensor's pose in the world, the vehicle pose composed with the mount."""
    return vehicle.compose(sensor_mount(config))
