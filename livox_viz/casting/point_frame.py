"""What a frame of points is to the exporters and the views, whoever made it.

Two kinds of frame exist: a :class:`~livox_viz.casting.scan.ScanFrame` that we cast
ourselves (we know the truth behind every int16 point) and a
:class:`~livox_viz.wire.received.ReceivedFrame` that came over the wire (we know only
what a client knows). Both offer the members of :class:`PointFrame`, which is all
an exporter or a view needs.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from livox_viz.core.poses import Pose


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
    reflectivity : (M,) uint8
        Livox's reflectivity byte (0-150 Lambertian 0-100 %, 151-255 retroreflective; 0 when unknown).
    tag : (M,) uint8
        Livox SDK1 tag: bits 0-1 spatial noise, 2-3 intensity noise, 4-5 return number.
    return_number : (M,) uint8
        1, 2, 3 in range order within the point's pulse.
    number_of_returns : (M,) uint8
        Points the pulse returned.
    """

    index: int
    timestamp: float
    sensor_pose: Pose
    end_pose: Pose
    t: np.ndarray
    range_m: np.ndarray
    xyz_int16: np.ndarray
    reflectivity: np.ndarray
    tag: np.ndarray
    return_number: np.ndarray
    number_of_returns: np.ndarray

    @property
    def xyz_decoded(self) -> np.ndarray: ...

    @property
    def xyz_world(self) -> np.ndarray: ...

    @property
    def xyz_world_decoded(self) -> np.ndarray: ...

    def __len__(self) -> int: ...
