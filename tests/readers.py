"""Point-cloud files: PLY and PCD (binary or ASCII), LAS 1.4, NPZ and CSV, streamed frame by frame.

Every writer takes frames one at a time (memory stays flat however long the
scan), writes into temporary files next to the destination and renames the
finished file over it on :meth:`PointCloudWriter.close`; on failure nothing is
left behind. Each file states its frame of reference (``sensor`` = the
decoded int16 points a RflySim client sees, sensor FRD metres; ``world`` =
world NED metres) in its header or metadata."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from livox_viz.core.errors import LivoxVizError


# Reading back (tests and users' own checks) ------------------------------------------
def read_pcd(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Read a PCD file written as ``DATA ascii`` or ``DATA binary`` (not binary_compressed).

    Returns
    -------
    fields : dict of str to (n,) arrays
        One array per field, plus ``"_comments"`` is not included.
    """
    path = Path(path)
    with open(path, "rb") as handle:
        header: dict[str, list[str]] = {}
        while True:
            line = handle.readline()
            if not line:
                raise LivoxVizError(f"{path}: PCD header has no DATA line")
            text = line.decode("ascii", "replace").strip()
            if not text or text.startswith("#"):
                continue
            key, *values = text.split()
            header[key.upper()] = values
            if key.upper() == "DATA":
                break
        names = header["FIELDS"]
        kinds = {("F", "4"): "<f4", ("F", "8"): "<f8", ("U", "4"): "<u4", ("I", "4"): "<i4",
                 ("U", "1"): "u1", ("I", "2"): "<i2", ("U", "2"): "<u2", ("I", "1"): "i1"}
        dtype = np.dtype([(n, kinds[(t, s)]) for n, t, s in zip(names, header["TYPE"], header["SIZE"], strict=True)])
        points = int(header["POINTS"][0])
        # PCD v0.7: POINTS is WIDTH * HEIGHT (PCL refuses a file where they disagree).
        if int(header["WIDTH"][0]) * int(header["HEIGHT"][0]) != points:
            raise LivoxVizError(f"{path}: WIDTH {header['WIDTH'][0]} x HEIGHT {header['HEIGHT'][0]} != POINTS {points}")
        mode = header["DATA"][0]
        if mode == "binary":
            data = np.frombuffer(handle.read(points * dtype.itemsize), dtype=dtype, count=points)
            return {name: data[name].copy() for name in names}
        if mode == "ascii":
            table = np.loadtxt(handle, ndmin=2) if points else np.zeros((0, len(names)))
            return {name: table[:, i].astype(dtype[name]) for i, name in enumerate(names)}
        raise LivoxVizError(f"{path}: PCD DATA {mode}; allowed: ascii or binary")
