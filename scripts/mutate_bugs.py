"""The deliberate bugs of issue 16 (and later ones), for ``scripts/mutate.py``: each must fail a test.

Each bug names the exact text it breaks (``old``, which must occur once in
``path``) and what it becomes (``new``). When the code changes so that
``old`` no longer matches, the mutation run says "not applicable" for that
bug: rewrite the entry for the new code rather than dropping it.
"""

from __future__ import annotations

DELIBERATE_BUGS: list[dict[str, str]] = [
    {
        "name": "raycast: the grazing-hit fallback forgets the local-origin offset",
        "path": "livox_viz/scene/raycast.py",
        "old": "np.broadcast_to(o - self.local_origin, (rows.size, 3))",
        "new": "np.broadcast_to(o, (rows.size, 3))",
    },
    {
        "name": "reassembler: a datagram longer than its length field is accepted",
        "path": "livox_viz/wire/rflysim.py",
        "old": "if length != len(datagram):",
        "new": "if length > len(datagram):",
    },
    {
        "name": "publish: pacing multiplied by the speed instead of divided",
        "path": "livox_viz/wire/transport.py",
        "old": "due = anchor_wall + (frame.timestamp - anchor_scan) / speed",
        "new": "due = anchor_wall + (frame.timestamp - anchor_scan) * speed",
    },
    {
        "name": "PCD: the header's WIDTH is one short",
        "path": "livox_viz/files/export.py",
        "old": 'f"WIDTH {self.count}"',
        "new": 'f"WIDTH {self.count - 1}"',
    },
    {
        "name": "GUI: density and coverage grids not rebuilt when the FOV changes",
        "path": "widgets/session.py",
        "old": "resize = config.point_rate != self.config.point_rate or config.field_of_view != "
               "self.config.field_of_view",
        "new": "resize = config.point_rate != self.config.point_rate",
    },
    {
        "name": "received frame: placed in the world with the inverse rotation",
        "path": "livox_viz/wire/received.py",
        "old": "self.xyz_decoded @ self.sensor_pose.rotation.T",
        "new": "self.xyz_decoded @ self.sensor_pose.rotation",
    },
    {
        "name": "shared memory: the written flag raised before the frame is in the block",
        "path": "livox_viz/wire/rflysim.py",
        "old": "        self._map[SHM_HEADER.size : SHM_HEADER.size + points.nbytes] = points.tobytes()\n",
        "new": "        self._map[0] = SHM_FLAG_WRITTEN\n"
               "        self._map[SHM_HEADER.size : SHM_HEADER.size + points.nbytes] = points.tobytes()\n",
    },
    {
        "name": "moving cast: each ray uses the pose one sample late",
        "owner": "h-motion",
        "path": "livox_viz/casting/scan.py",
        "old": "origin, directions_world = self.track.rays(t, directions_sensor, into)",
        "new": "origin, directions_world = self.track.rays(t + 1.0 / config.point_rate, directions_sensor, into)",
    },
    {
        "name": "odometry: the twist in the world frame instead of the body frame",
        "owner": "h-motion",
        "path": "livox_viz/files/rosbag.py",
        "old": 'body_velocity = flu_from_frd(np.einsum("nji,nj->ni", rotation, velocity))',
        "new": "body_velocity = flu_from_frd(velocity)",
    },
    {
        "name": "returns: a whole pulse's range compared as its square against the blind zone (issue 43)",
        "path": "livox_viz/casting/return_kernels.py",
        "old": "if triangle[i] >= 0 and distance[i] >= blind:",
        "new": "if triangle[i] >= 0 and distance[i] * distance[i] >= blind:",
    },
    {
        "name": "field of view: a polygon's outline left open, its last side not drawn (issue 43)",
        "path": "livox_viz/config/fov.py",
        "old": "return np.vstack([self.outline_deg, self.outline_deg[:1]])",
        "new": "return self.outline_deg",
    },
]
