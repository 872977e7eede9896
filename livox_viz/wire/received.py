"""A frame received from RflySim (or our publisher), as a client knows it.

It offers the members of :class:`~livox_viz.casting.point_frame.PointFrame`, so
the exporters and views take it like a scanned frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from livox_viz.casting.codec import decode_int16
from livox_viz.casting.directions import xy_from_directions
from livox_viz.core.poses import Pose
from livox_viz.wire.rflysim import LivoxFrame


@dataclass(frozen=True)
class ReceivedFrame:
    """A frame received from RflySim (or our publisher), decoded with the sensor's range.

    Per-point times are not on the wire: every point carries the frame's
    timestamp. Ranges and angles are those of the decoded int16 points.

    Parameters
    ----------
    wire : LivoxFrame
        What arrived: timestamp, posAng and int16 points.
    range_max : float
        The int16 scale, metres.
    frame_rate : float
        Frames per second (``DataCheckFreq``), to number the frame from its timestamp.
    """

    wire: LivoxFrame
    range_max: float
    frame_rate: float

    def __len__(self) -> int:
        return int(self.wire.xyz_int16.shape[0])

    @property
    def index(self) -> int:
        """Frame number, from the timestamp (clipped into int64: a sender may stamp anything)."""
        return int(np.clip(round(self.wire.timestamp * self.frame_rate), -(2**62), 2**62))

    @property
    def timestamp(self) -> float:
        return self.wire.timestamp

    @property
    def xyz_int16(self) -> np.ndarray:
        return self.wire.xyz_int16

    @cached_property
    def sensor_pose(self) -> Pose:
        """The posAng sent with the frame."""
        pose = self.wire.pos_ang
        return Pose(tuple(pose[:3]), *pose[3:])

    @property
    def end_pose(self) -> Pose:
        """The wire carries one pose per frame: the same as :attr:`sensor_pose`."""
        return self.sensor_pose

    @cached_property
    def t(self) -> np.ndarray:
        """``(M,)`` float64 the frame's timestamp for every point."""
        return np.full(len(self), self.wire.timestamp)

    @cached_property
    def xyz_decoded(self) -> np.ndarray:
        """``(M, 3)`` float64 sensor FRD, metres."""
        return decode_int16(self.wire.xyz_int16, self.range_max)

    @cached_property
    def range_m(self) -> np.ndarray:
        """``(M,)`` float64 length of each decoded point, metres."""
        return np.linalg.norm(self.xyz_decoded, axis=1)

    @cached_property
    def xy_deg(self) -> np.ndarray:
        """``(M, 2)`` float64 pattern angles recovered from the decoded points (quantised by the int16 step)."""
        return xy_from_directions(self.xyz_decoded)

    @cached_property
    def xyz_world_decoded(self) -> np.ndarray:
        """``(M, 3)`` float64 the decoded points in the world NED frame."""
        return self.sensor_pose.origin + self.xyz_decoded @ self.sensor_pose.rotation.T

    @property
    def xyz_world(self) -> np.ndarray:
        """Same as :attr:`xyz_world_decoded`: a received frame knows no truer point."""
        return self.xyz_world_decoded
