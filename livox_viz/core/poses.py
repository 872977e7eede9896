"""Rigid poses in an NED/FRD parent frame: position in metres, [roll, pitch, yaw] in radians.

A :class:`Pose` is what ``--pose``, a scene's vehicle pose, the sensor mount and
RflySim's ``posAng`` hold; its rotation is :func:`~livox_viz.core.rotations.euler_matrix`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from livox_viz.core.errors import LivoxVizError, quoted
from livox_viz.core.rotations import euler_matrix, matrix_to_euler, quat_from_matrix

#: The farthest a ``--pose`` may place the vehicle from the world origin, metres (beyond the Earth's radius).
MAX_POSITION_M = 1e7
#: The largest angle a pose or a mount may give, radians: some 1,600 turns, where a float64 still holds an angle to
#: 2e-12 rad. At 1e20 rad the spacing of floats is 16,000 rad: the orientation would be noise, said as a number.
MAX_ANGLE_RAD = 1e4


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
            raise LivoxVizError(f"pose {quoted(values)}; allowed: 6 finite numbers x,y,z (m), roll,pitch,yaw (rad)")
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
                f"pose {quoted(text)} does not parse; allowed: x,y,z,roll,pitch,yaw (6 numbers, metres and radians)"
            ) from None
        if len(values) != 6:
            raise LivoxVizError(f"pose {quoted(text)} has {len(values)} numbers; allowed: x,y,z,roll,pitch,yaw (6)")
        return cls.from_values(values, f"pose {quoted(text)}")

    @classmethod
    def from_values(cls, values: object, where: str) -> Pose:
        """A pose from ``[x, y, z, roll, pitch, yaw]`` (metres, radians) as a user wrote them (``--pose``, a scene's
        ``vehicle_pose``): six finite numbers, the position within :data:`MAX_POSITION_M` of the origin.

        Parameters
        ----------
        values : object
            What the user gave; anything but six such numbers is refused, naming ``where``.
        where : str
            The value in the user's terms, e.g. ``"scene.json: 'vehicle_pose' = [...]"``.
        """
        allowed = ("allowed: x, y, z (m, NED, each within "
                   f"{MAX_POSITION_M:g} m of the origin) and roll, pitch, yaw (rad, each within {MAX_ANGLE_RAD:g}): "
                   "6 finite numbers")
        if not isinstance(values, (list, tuple)) or len(values) != 6 or any(
                isinstance(v, bool) or not isinstance(v, (int, float)) for v in values):
            raise LivoxVizError(f"{where}: {allowed}")
        numbers = [float(v) for v in values]
        if not all(math.isfinite(v) for v in numbers):
            raise LivoxVizError(f"{where}: NaN or infinite; {allowed}")
        if not all(abs(v) <= MAX_POSITION_M for v in numbers[:3]):  # 1e300 would overflow the float32 ray casts
            raise LivoxVizError(f"{where}: a position beyond {MAX_POSITION_M:g} m; allowed: |x|, |y|, |z| "
                                f"<= {MAX_POSITION_M:g} m (a local NED frame)")
        if not all(abs(v) <= MAX_ANGLE_RAD for v in numbers[3:]):
            raise LivoxVizError(f"{where}: an angle beyond {MAX_ANGLE_RAD:g} rad; allowed: |roll|, |pitch|, |yaw| "
                                f"<= {MAX_ANGLE_RAD:g} rad")
        return cls(tuple(numbers[:3]), *numbers[3:])  # type: ignore[arg-type]






def pose_quaternion(pose: Pose) -> np.ndarray:
    """``(4,)`` the orientation of a :class:`Pose` as [x, y, z, w]."""
    return quat_from_matrix(pose.rotation)


def pose_from_quaternion(position: np.ndarray, quaternion: np.ndarray) -> Pose:
    """A :class:`Pose` from a position ``(3,)`` and a unit quaternion ``(4,)`` [x, y, z, w] (Z-Y-X Euler angles)."""
    x, y, z, w = (float(v) for v in quaternion)
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return Pose(tuple(float(v) for v in position), roll, pitch, yaw)
