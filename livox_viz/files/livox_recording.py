"""A recording of a Livox head, whatever file it came from: its points in firing order, with each one's time and laser.

What :func:`~livox_viz.files.lvx_read.read_lvx` (LVX2, LVX 1.1) and
:func:`~livox_viz.files.livox_bag.read_livox_bag` (ROS 1 and ROS 2 bags of the
Livox drivers' ``CustomMsg`` or ``PointCloud2``) give, so that whatever uses a
recording (a reference table for ``compare`` and ``fit``, a preset fitted from
it) reads one form. Rows are firings' returns in the order the head fired them
(a dual or triple return firing gives its returns one after the other, at one
time); a firing that returned nothing is kept where the file keeps it, as
(0, 0, 0) with :attr:`LivoxRecording.no_return` set, so its time and laser
still say where the pattern was.

Frame of the points: the head's own, as Livox writes it: x forward, y left, z
up, metres (REP 103's FLU; our sensor FRD is ``(x, -y, -z)`` of it). The
device's extrinsics (its mount) are in :attr:`LivoxDevice.extrinsics`, not
applied.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LivoxDevice:
    """One device of a recording.

    Attributes
    ----------
    serial : str
        The lidar's serial number (broadcast code), "" when the file gives none.
    device_type : int
        Livox's device type (9 Mid-360, 10 HAP; 1 Mid-40/100, 2 Tele-15, 3 Horizon, 6 Mid-70, 7 Avia), -1 unknown.
    name : str
        The head's name ("Mid-360"), or ``"device type N"``.
    extrinsic_enable : bool
    extrinsics : (6,) tuple of float
        roll, pitch, yaw (degrees, ``Rz(yaw) Ry(pitch) Rx(roll)``) and x, y, z (metres): the head in its vehicle.
    """

    serial: str
    device_type: int
    name: str
    extrinsic_enable: bool = False
    extrinsics: tuple[float, float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class LivoxRecording:
    """Points of a Livox recording in firing order.

    Attributes
    ----------
    points_m : (n, 3) float64
        x forward, y left, z up, metres (0, 0, 0 where nothing returned).
    times_s : (n,) float64
        Each point's time, seconds on the file's clock (a scan of ours: seconds since the scan start), rebuilt as
        the drivers rebuild it: a package's timestamp plus the firing's place times the point interval.
    lasers : (n,) uint8
        The laser (the drivers' ``line``).
    reflectivity : (n,) uint8
    tags : (n,) uint8
        Livox's tag byte (SDK1: bits 4-5 the return number).
    return_number : (n,) uint8
        1, 2, 3: the return's place within its firing (1 for single return data).
    no_return : (n,) bool
        The firing returned nothing (the file holds (0, 0, 0)).
    device_index : (n,) uint8
        Which of :attr:`devices` the point is from.
    devices : tuple of LivoxDevice
    source : str
        The format read: ``"LVX2"``, ``"LVX 1.1"``, ``"ROS 1 bag"``, ``"ROS 2 bag"``.
    skipped : dict of str to int
        What was read past and not kept, e.g. ``{"IMU packages": 600}``.
    """

    points_m: np.ndarray
    times_s: np.ndarray
    lasers: np.ndarray
    reflectivity: np.ndarray
    tags: np.ndarray
    return_number: np.ndarray
    no_return: np.ndarray
    device_index: np.ndarray
    devices: tuple[LivoxDevice, ...]
    source: str
    skipped: dict[str, int]

    def __len__(self) -> int:
        return int(self.times_s.shape[0])

    @property
    def device_type(self) -> int:
        """The first device's type (-1 without a device)."""
        return self.devices[0].device_type if self.devices else -1

    def returns(self) -> LivoxRecording:
        """The points that are returns (no-return firings left out)."""
        return self.subset(~self.no_return)

    def subset(self, keep: np.ndarray) -> LivoxRecording:
        """The rows ``keep`` (a boolean mask or indices) of every per-point array."""
        return LivoxRecording(self.points_m[keep], self.times_s[keep], self.lasers[keep], self.reflectivity[keep],
                              self.tags[keep], self.return_number[keep], self.no_return[keep],
                              self.device_index[keep], self.devices, self.source, dict(self.skipped))

    @staticmethod
    def join(parts: list[LivoxRecording], devices: tuple[LivoxDevice, ...], source: str,
             skipped: dict[str, int]) -> LivoxRecording:
        """One recording of ``parts`` (chunks of one file, in order)."""
        def cat(name: str, dtype, shape: tuple[int, ...] = ()) -> np.ndarray:
            arrays = [getattr(part, name) for part in parts]
            return np.concatenate(arrays) if arrays else np.zeros((0, *shape), dtype)

        return LivoxRecording(cat("points_m", np.float64, (3,)), cat("times_s", np.float64), cat("lasers", np.uint8),
                              cat("reflectivity", np.uint8), cat("tags", np.uint8), cat("return_number", np.uint8),
                              cat("no_return", bool), cat("device_index", np.uint8), devices, source, skipped)
