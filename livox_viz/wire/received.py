"""A frame received from RflySim (or our publisher), as a client knows it, and how a recording numbers them.

:class:`ReceivedFrame` offers the members of
:class:`~livox_viz.casting.point_frame.PointFrame`, so the exporters and views
take it like a scanned frame. :class:`RecordingClock` gives each frame of a
recording a unique increasing index and a time that never goes back, whatever
the senders do (restart, or send side by side), and keeps the sender's own
frame number and time beside them.
"""

from __future__ import annotations

import math
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
    timestamp. Ranges and angles are those of the decoded int16 points. Nor are
    intensities or tags: reflectivity 0, tag 0x10, return 1 of 1. A v3 frame's
    fourth value a point is kept as it came (:attr:`channel4`). Points that came
    in the world frame (the v3 Mid-360's) are placed in the sensor frame with
    the frame's posAng, so both frames are there whichever the wire used.

    Parameters
    ----------
    wire : LivoxFrame
        What arrived: timestamp, posAng and int16 points.
    range_max : float
        The int16 scale, metres.
    frame_rate : float
        Frames per second (``DataCheckFreq``), to number the frame from its timestamp.
    number : int, optional
        The frame's index in a recording (see :class:`RecordingClock`); None: the sender's frame number.
    recording_time : float, optional
        The frame's time in a recording, seconds; None: the sender's timestamp.
    session : int
        Which sender run of the recording it belongs to (a new one for each sender and each restart).
    plane : {"boresight", "panorama"}
        The sensor's pattern plane, for :attr:`xy_deg` (a Mid-360's points are azimuth and elevation).
    """

    wire: LivoxFrame
    range_max: float
    frame_rate: float
    number: int | None = None
    recording_time: float | None = None
    session: int = 0
    plane: str = "boresight"

    def __len__(self) -> int:
        return int(self.wire.xyz_int16.shape[0])

    @property
    def sender_index(self) -> int:
        """The sender's frame number: the new header's frame id, else from its timestamp (clipped into int32: a
        sender may stamp anything)."""
        if self.wire.frame_id is not None:
            return int(self.wire.frame_id)
        return int(np.clip(round(self.wire.timestamp * self.frame_rate), -(2**31), 2**31 - 1))

    @cached_property
    def channel4(self) -> np.ndarray:
        """``(M,)`` int16 a v3 frame's fourth value of each point as sent (0 for a frame of three values a point:
        RflySim documents nothing for it; its ROS publisher calls it ``seg``)."""
        if self.wire.channel4 is None:
            return np.zeros(len(self), dtype=np.int16)
        return self.wire.channel4

    @property
    def sender_time(self) -> float:
        """The sender's timestamp, seconds."""
        return self.wire.timestamp

    @property
    def index(self) -> int:
        """The frame's number: its index in the recording when numbered, else the sender's."""
        return self.sender_index if self.number is None else self.number

    @property
    def timestamp(self) -> float:
        """The frame's time: in the recording when numbered, else the sender's, seconds."""
        return self.wire.timestamp if self.recording_time is None else self.recording_time

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
        """``(M,)`` float64 the frame's :attr:`timestamp` for every point."""
        return np.full(len(self), self.timestamp)

    @cached_property
    def xyz_decoded(self) -> np.ndarray:
        """``(M, 3)`` float64 sensor FRD, metres (world points brought into the sensor frame with posAng)."""
        decoded = decode_int16(self.wire.xyz_int16, self.range_max)
        if self.wire.points_frame == "world":
            pose = self.sensor_pose
            return (decoded - pose.origin) @ pose.rotation
        return decoded

    @cached_property
    def range_m(self) -> np.ndarray:
        """``(M,)`` float64 length of each decoded point, metres."""
        return np.linalg.norm(self.xyz_decoded, axis=1)

    @cached_property
    def xy_deg(self) -> np.ndarray:
        """``(M, 2)`` float64 pattern angles recovered from the decoded points (quantised by the int16 step)."""
        return xy_from_directions(self.xyz_decoded, self.plane)

    @cached_property
    def xyz_world_decoded(self) -> np.ndarray:
        """``(M, 3)`` float64 the decoded points in the world NED frame."""
        if self.wire.points_frame == "world":
            return decode_int16(self.wire.xyz_int16, self.range_max)
        return self.sensor_pose.origin + self.xyz_decoded @ self.sensor_pose.rotation.T

    @property
    def xyz_world(self) -> np.ndarray:
        """Same as :attr:`xyz_world_decoded`: a received frame knows no truer point."""
        return self.xyz_world_decoded

    @cached_property
    def reflectivity(self) -> np.ndarray:
        """``(M,)`` uint8 zeros: RflySim's wire carries no intensity."""
        return np.zeros(len(self), dtype=np.uint8)

    @cached_property
    def tag(self) -> np.ndarray:
        """``(M,)`` uint8 0x10 (return 1, no noise flags): the wire carries one point per ray."""
        return np.full(len(self), 0x10, dtype=np.uint8)

    @cached_property
    def return_number(self) -> np.ndarray:
        """``(M,)`` uint8 ones."""
        return np.ones(len(self), dtype=np.uint8)

    @property
    def number_of_returns(self) -> np.ndarray:
        """``(M,)`` uint8 ones."""
        return self.return_number


#: Per-point fields of a recording besides the usual ones (see ``PointCloudWriter(extra_fields=...)``).
RECORDING_FIELDS: tuple[tuple[str, str], ...] = (("sender_frame", "<i4"), ("sender_time", "<f8"), ("session", "<u4"),
                                                 ("channel4", "<i4"))
#: The columns of :attr:`RecordingClock.table`, one row per recorded frame.
RECORDING_TABLE_COLUMNS = ("index", "session", "sender_frame", "sender_time", "t")


@dataclass
class _Session:
    source: str
    number: int
    first_sender_time: float
    start: float | None  # the recording's time of its first frame; None: the sender's own time (first session)
    last_sender_time: float


class RecordingClock:
    """Numbers the frames of a recording and gives them a time that never goes back.

    Every frame gets the next index (0, 1, 2, ...), whatever its sender calls
    it. Frames belong to *sessions*: one per sender (source address) and a new
    one whenever that sender's timestamps go back (a restarted publisher or
    RflySim). The first session keeps the sender's own time; a later session
    starts after the newest time recorded so far, by the wall time that passed
    since that frame arrived (at least one frame period), and then steps
    exactly as its sender's timestamps do.

    Parameters
    ----------
    range_max : float
        The int16 scale, metres.
    frame_rate : float
        Frames per second (``DataCheckFreq``).

    Attributes
    ----------
    sessions : list of str
        The source of each session, in order.
    restarts : int
        Sessions that began because a sender's time went back.
    table : list of tuple
        One row per frame: :data:`RECORDING_TABLE_COLUMNS`.
    """

    def __init__(self, range_max: float, frame_rate: float) -> None:
        self.range_max = range_max
        self.frame_rate = frame_rate
        self.sessions: list[str] = []
        self.restarts = 0
        self.table: list[tuple[int, int, int, float, float]] = []
        self._by_source: dict[str, _Session] = {}
        self._newest: tuple[float, float] | None = None  # (recording time, arrival) of the newest frame

    def number(self, wire: LivoxFrame, arrival: float) -> ReceivedFrame:
        """The frame, numbered, with its recording time.

        Parameters
        ----------
        wire : LivoxFrame
            What arrived (a finite timestamp).
        arrival : float
            When it arrived on the receiver's monotonic clock, seconds.
        """
        session = self._by_source.get(wire.source)
        if session is None or wire.timestamp < session.last_sender_time:
            if session is not None:
                self.restarts += 1
            start = None
            if self._newest is not None:
                newest, newest_arrival = self._newest
                start = newest + max(arrival - newest_arrival, 1.0 / self.frame_rate)
            session = _Session(wire.source, len(self.sessions), wire.timestamp, start, wire.timestamp)
            self._by_source[wire.source] = session
            self.sessions.append(wire.source)
        session.last_sender_time = wire.timestamp
        if session.start is None:
            time = wire.timestamp
        else:
            time = session.start + (wire.timestamp - session.first_sender_time)
        if not math.isfinite(time):  # an absurd sender time (1e308): keep the recording's clock finite
            time = session.start if session.start is not None else 0.0
        frame = ReceivedFrame(wire, self.range_max, self.frame_rate, len(self.table), time, session.number)
        self.table.append((frame.index, session.number, frame.sender_index, wire.timestamp, time))
        if self._newest is None or time >= self._newest[0]:
            self._newest = (time, arrival)
        return frame

    def forget_last(self) -> None:
        """Take back the last frame numbered (a recording that ends without it): its row of :attr:`table`, and its
        session if it began one."""
        number = self.table.pop()[1]
        if number == len(self.sessions) - 1 and not any(row[1] == number for row in self.table):
            source = self.sessions.pop()
            self.restarts -= int(source in self.sessions)  # it began as a restart of that sender

    def table_array(self) -> np.ndarray:
        """``(n, 5)`` float64 :attr:`table`."""
        return np.array(self.table, dtype=np.float64).reshape(-1, len(RECORDING_TABLE_COLUMNS))
