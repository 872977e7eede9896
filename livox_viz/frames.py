"""What a frame of points is to the exporters and the GUI, whoever made it.

Two kinds of frame exist: a :class:`~livox_viz.scan.ScanFrame` that we cast
ourselves (we know the truth behind every int16 point) and a
:class:`ReceivedFrame` that came over the wire (we know only what a client
knows). Both offer the members of :class:`PointFrame`, which is all an
exporter or a view needs.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Protocol

import numpy as np

from .codec import decode_int16
from .directions import xy_from_directions
from .poses import Pose
from .rflysim import LivoxFrame


class PointFrame(Protocol):
    """A frame of points as exporters and views use it.

    Attributes
    ----------
    index : int
        Frame number from the scan start.
    timestamp : float
        Seconds since the scan start.
    sensor_pose : Pose
        The sensor's pose in the world (NED) at the frame's start.
    end_pose : Pose
        The sensor's pose at the frame's end (the same for a fixed sensor or a received frame).
    t : (M,) float64
        Time of each point, seconds.
    range_m : (M,) float64
        Range of each point, metres.
    xyz_int16 : (M, 3) int16
        The published encoding, sensor FRD.
    xyz_decoded : (M, 3) float64
        Decoded points, sensor FRD, metres.
    xyz_world : (M, 3) float64
        The points in the world NED frame, metres (true hits for a scan, decoded for a received frame).
    xyz_world_decoded : (M, 3) float64
        The decoded points placed in the world with the frame's pose.
    """

    index: int
    timestamp: float
    sensor_pose: Pose
    end_pose: Pose
    t: np.ndarray
    range_m: np.ndarray
    xyz_int16: np.ndarray

    @property
    def xyz_decoded(self) -> np.ndarray: ...

    @property
    def xyz_world(self) -> np.ndarray: ...

    @property
    def xyz_world_decoded(self) -> np.ndarray: ...

    def __len__(self) -> int: ...


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
