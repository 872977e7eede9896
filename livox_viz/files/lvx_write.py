"""Frames of a scan as LVX2 or LVX 1.1 bytes: packages of consecutive firings, 50 ms frames, streamed.

The layouts are :mod:`~livox_viz.files.lvx_format`'s. A scan's firings are cut
into packages as the head's UDP packets carry them: package ``p`` holds the
firings ``p * n .. p * n + n - 1`` of the stream (``n`` = 96, or 100 for a
Mid-40, 48 and 30 pulses for the dual and triple types), each in its place,
a firing that returned nothing as (0, 0, 0) with reflectivity and tag 0. The
package's timestamp is its first firing's scan time (ns, timestamp type 0: no
sync source), so a driver's ``timestamp + i * interval`` and ``i % lines``
give each point its time and laser back. Points are the decoded points every
other format holds (the int16 wire's), turned from our sensor FRD into Livox's
FLU (x forward, y left, z up) and rounded to whole millimetres.

Packages go into the 50 ms frame their timestamp falls in; a frame is written
whole once a package of a later one comes, so at most one frame (50 ms of
packages) and one unfinished package are held, however long the scan.
:class:`LvxEncoder` returns the bytes and its next state without keeping
either (:meth:`LvxEncoder.pack`), so a writer whose write fails keeps the state
of the frames written (:meth:`LvxEncoder.commit` after a good write only).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from livox_viz.core.errors import LivoxVizError
from livox_viz.core.rotations import flu_from_frd
from livox_viz.files.lvx_format import (
    FRAME_HEADER,
    FRAME_MS,
    LVX1_DEVICE,
    LVX1_PACKAGE,
    LVX1_PACKAGE_VERSION,
    LVX1_VERSION,
    LVX2_DEVICE,
    LVX2_DEVICE_LIDAR_TYPE,
    LVX2_LIDAR_TYPE,
    LVX2_PACKAGE,
    LVX2_VERSION,
    MAGIC_CODE,
    PRIVATE_HEADER,
    PUBLIC_HEADER,
    SIGNATURE,
    LivoxHead,
)

#: The serial number our files give the one device (15 characters and the terminating NUL).
LIDAR_SN = b"LIVOXVIZSIM0001"
#: LVX2's lidar id of the device and its packages: the head's IP address as a number, as Livox Viewer 2 records it
#: (192.168.1.100 here).
LVX2_LIDAR_ID = 0xC0A80164
#: LVX 1.1's lidar id in a package (1: the first of a hub slot's; a Mid-100 numbers its three 1, 2, 3).
LVX1_LIDAR_ID = 1
FRAME_NS = FRAME_MS * 1_000_000


def file_header(head: LivoxHead) -> bytes:
    """The public header, private header and the one device's info."""
    lvx2 = head.model.suffix == ".lvx2"
    public = np.zeros(1, PUBLIC_HEADER)
    public["signature"] = SIGNATURE
    public["version"] = LVX2_VERSION if lvx2 else LVX1_VERSION
    public["magic_code"] = MAGIC_CODE
    private = np.zeros(1, PRIVATE_HEADER)
    private["frame_duration"] = FRAME_MS
    private["device_count"] = 1
    device = np.zeros(1, LVX2_DEVICE if lvx2 else LVX1_DEVICE)
    device["lidar_sn"] = LIDAR_SN
    if lvx2:
        device["lidar_id"] = LVX2_LIDAR_ID
        device["lidar_type"] = LVX2_DEVICE_LIDAR_TYPE
    device["device_type"] = head.model.device_type
    device["extrinsic_enable"] = 1
    for name, value in zip(("roll", "pitch", "yaw", "x", "y", "z"), head.extrinsics(), strict=True):
        device[name] = value
    return public.tobytes() + private.tobytes() + device.tobytes()


@dataclass(frozen=True)
class EncoderState:
    """Where an :class:`LvxEncoder` stands: nothing in it is shared with another state (a new one per frame)."""

    #: File offset of the frame being gathered (the next frame header's ``current_offset``).
    offset: int
    #: Frames written.
    frame_index: int = 0
    #: The 50 ms period (timestamp // 50 ms) of the frame being gathered, or None before the first package.
    frame_key: int | None = None
    #: The frame's packages so far, bytes.
    chunks: tuple[bytes, ...] = ()
    #: The unfinished package: its first firing's stream index and its returns, ``(firings, echoes)`` records.
    pending_start: int | None = None
    pending: np.ndarray | None = field(default=None, repr=False)
    #: Packages made (LVX2's udp counter is this modulo 65536).
    packages: int = 0


@dataclass(frozen=True)
class Packed:
    """One call's bytes to append (whole frames) and the state after them."""

    data: tuple[bytes, ...]
    state: EncoderState


class LvxEncoder:
    """Turns a scan's frames into an LVX2 or LVX 1.1 file's bytes.

    Parameters
    ----------
    head : LivoxHead
    """

    def __init__(self, head: LivoxHead) -> None:
        self.head = head
        data_type = head.data_type
        assert data_type is not None and data_type.point is not None  # LivoxHead refuses the others
        self.data_type = data_type
        self.lvx2 = head.model.suffix == ".lvx2"
        self.header = file_header(head)
        package = LVX2_PACKAGE if self.lvx2 else LVX1_PACKAGE
        self.record = np.dtype([("head", package),
                                ("points", data_type.point, (data_type.firings, data_type.echoes))])
        self.state = EncoderState(offset=len(self.header))

    def timestamp_ns(self, slot: np.ndarray) -> np.ndarray:
        """``(n,)`` int64 the scan time of firings ``slot`` (stream indices), nanoseconds, rounded: integer arithmetic
        (float64 would lose nanoseconds past 104 days of 1e9 ns)."""
        rate = int(self.head.rate)
        return (np.asarray(slot, dtype=np.int64) * 2_000_000_000 + rate) // (2 * rate)

    def pack(self, frame) -> Packed:
        """The bytes of the frames ``frame``'s firings complete, and the state after them.

        Parameters
        ----------
        frame : ScanFrame
            Needs ``stream_index``, ``ray_count`` and ``timestamp`` (a scan's frame: a frame received from the wire
            has no firing order and is refused).

        Raises
        ------
        LivoxVizError
            A frame without firing order, or whose firings go back before the file's.
        """
        if getattr(frame, "stream_index", None) is None or getattr(frame, "ray_count", None) is None:
            raise LivoxVizError(f"{self.head.model.suffix} needs each point's firing (a scan's frames); allowed: "
                                "frames of scan, batch or the window's export")
        state = self.state
        firings, echoes = self.data_type.firings, self.data_type.echoes
        start = round(frame.timestamp * self.head.rate)
        stop = start + int(frame.ray_count)
        base = state.pending_start if state.pending_start is not None else start // firings * firings
        if start < base:
            raise LivoxVizError(f"firings from {start} come after the file's {base}; allowed: frames in firing order")
        spanned = -(-(stop - base) // firings)
        points = np.zeros((spanned, firings, echoes), self.data_type.point)
        if state.pending is not None:
            points[0] = state.pending
        if len(frame):
            index = np.asarray(frame.stream_index, dtype=np.int64) - base
            echo = np.asarray(frame.return_number, dtype=np.int64) - 1
            keep = (echo >= 0) & (echo < echoes) & (index >= 0) & (index < spanned * firings)
            index, echo = index[keep], echo[keep]
            mm = np.rint(flu_from_frd(frame.xyz_decoded[keep]) * 1000.0).astype(np.int32)
            where = (index // firings, index % firings, echo)
            slots = points[where]
            slots["x"], slots["y"], slots["z"] = mm[:, 0], mm[:, 1], mm[:, 2]
            slots["reflectivity"] = frame.reflectivity[keep]
            if "tag" in self.data_type.point.names:
                slots["tag"] = frame.tag[keep]
            points[where] = slots
        whole = (stop - base) // firings
        pending = points[whole].copy() if whole < spanned else None
        return self._frames(state, points[:whole], base, pending, base + whole * firings if pending is not None
                            else None)

    def _frames(self, state: EncoderState, points: np.ndarray, base: int, pending: np.ndarray | None,
                pending_start: int | None) -> Packed:
        """Packages of ``points`` (``(n, firings, echoes)`` records, the first at firing ``base``) gathered into 50 ms
        frames: the whole frames' bytes and the state after them."""
        count = len(points)
        firings = self.data_type.firings
        stamps = self.timestamp_ns(base + np.arange(count, dtype=np.int64) * firings)
        records = np.zeros(count, self.record)
        head = records["head"]
        head["timestamp"] = stamps
        head["data_type"] = self.data_type.number
        if self.lvx2:
            head["lidar_id"] = LVX2_LIDAR_ID
            head["lidar_type"] = LVX2_LIDAR_TYPE
            head["udp_counter"] = (state.packages + np.arange(count)) % 65536
            head["length"] = self.data_type.points_bytes
            head["frame_counter"] = (stamps // FRAME_NS) % 256
        else:
            head["version"] = LVX1_PACKAGE_VERSION
            head["lidar_id"] = LVX1_LIDAR_ID
        records["head"] = head
        records["points"] = points
        data = records.tobytes()
        size = self.record.itemsize
        keys = stamps // FRAME_NS
        cuts = np.flatnonzero(np.diff(keys)) + 1 if count else np.array([], dtype=np.int64)
        out: list[bytes] = []
        offset, index, key, chunks = state.offset, state.frame_index, state.frame_key, list(state.chunks)
        for first, last in zip([0, *cuts.tolist()], [*cuts.tolist(), count], strict=True):
            if first == last:
                continue
            group = int(keys[first])
            if key is not None and group != key and chunks:
                whole = self._frame_bytes(offset, index, chunks)
                out.append(whole)
                offset, index, chunks = offset + len(whole), index + 1, []
            key = group
            chunks.append(data[first * size: last * size])
        return Packed(tuple(out), EncoderState(offset, index, key, tuple(chunks), pending_start, pending,
                                               state.packages + count))

    @staticmethod
    def _frame_bytes(offset: int, index: int, chunks: list[bytes]) -> bytes:
        body = b"".join(chunks)
        header = np.zeros(1, FRAME_HEADER)
        header["current_offset"] = offset
        header["next_offset"] = offset + FRAME_HEADER.itemsize + len(body)
        header["frame_index"] = index
        return header.tobytes() + body

    def commit(self, packed: Packed) -> None:
        """Take the state after ``packed``, once its bytes are written."""
        self.state = packed.state

    def finish(self) -> bytes:
        """The last bytes: the unfinished package (its firings after the scan's end as no returns) and the frame
        being gathered."""
        state, done = self.state, b""
        if state.pending is not None:
            assert state.pending_start is not None
            packed = self._frames(state, state.pending[None], state.pending_start, None, None)
            state, done = packed.state, b"".join(packed.data)
        if not state.chunks:
            return done
        return done + self._frame_bytes(state.offset, state.frame_index, list(state.chunks))
