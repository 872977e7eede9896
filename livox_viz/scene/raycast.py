"""First-hit ray casting against a triangle mesh: Embree, and trimesh's numpy intersector.

Both backends share one interface, :meth:`distances`, with documented shapes;
a ray that hits nothing within ``max_distance`` gets ``inf``. :meth:`hits` also
says which triangle each ray met (the return model needs its material and
normal); ``face_planes`` holds every triangle's unit normal and offset.

Embree works in float32. The mesh is moved to its own origin (the centre of
its bounding box) before the conversion, so precision depends on the scene's
size, not on where it sits in the world: a range is good to about 1e-7 of the
scene's size (0.1 mm in a 1 km scene), far below the int16 step of the
published points (18 mm at 600 m). That is the default. With ``exact=True``
the distance of every hit is recomputed in float64 from the plane of the
triangle Embree found (about a tenth more time).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from typing import TYPE_CHECKING, Protocol, TypeVar

import numpy as np

from livox_viz.core.compiled import LazyKernels
from livox_viz.core.errors import LivoxVizError
from livox_viz.core.portable import usable_cores

if TYPE_CHECKING:
    import trimesh


#: Most rays in one part of a call (parts are taken by the calling thread and the workers as each comes free).
PART_RAYS = 65_536
#: Fewest rays in one part of a call split over threads (fewer are not worth a hand-over).
LEAST_RAYS = 2048

_this_thread = threading.local()
T = TypeVar("T")


@contextmanager
def casting_in_this_thread() -> Iterator[None]:
    """Within it, the calling thread's :meth:`EmbreeCaster.distances` calls cast every ray in that thread.

    For callers that already keep every core busy, such as frames cast side by side
    (:meth:`~livox_viz.casting.scan.LidarScanner.frames`): handing their parts to the
    caster's worker threads as well would only add hand-overs (a tenth more CPU time).
    """
    before = getattr(_this_thread, "inline", False)
    _this_thread.inline = True
    try:
        yield
    finally:
        _this_thread.inline = before


class RayCaster(Protocol):
    """What every backend offers."""

    def distances(
        self, origins: np.ndarray, directions: np.ndarray, max_distance: float = np.inf
    ) -> np.ndarray:
        """Distance along each ray to its first hit.

        Parameters
        ----------
        origins : (n, 3) or (3,) float
            Ray origins, metres, world frame; one row is used for all rays.
        directions : (n, 3) float
            Unit ray directions.
        max_distance : float
            Hits farther than this are misses, metres.

        Returns
        -------
        distance : (n,) float64
            Metres; ``inf`` where the ray hits nothing within ``max_distance``.
        """
        ...


def _check_rays(origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    origins = np.asarray(origins, dtype=np.float64)
    directions = np.asarray(directions)
    if directions.dtype != np.float32:  # float32 (what Embree takes) passes as it is
        directions = directions.astype(np.float64, copy=False)
    if directions.ndim != 2 or directions.shape[1] != 3:
        raise LivoxVizError(f"directions have shape {directions.shape}; allowed: (n, 3)")
    if origins.shape == (3,):
        origins = origins[None, :]
    if origins.ndim != 2 or origins.shape[1] != 3 or origins.shape[0] not in (1, directions.shape[0]):
        raise LivoxVizError(f"origins have shape {origins.shape}; allowed: (3,), (1, 3) or (n, 3) with n rays")
    return origins, directions


class EmbreeCaster:
    """First hits through Embree (``embreex``), rays split across threads.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The scene, metres.
    threads : int, optional
        Worker threads (Embree releases the GIL); default the cores this process may use.
    exact : bool
        Recompute each hit's distance in float64 from its triangle's plane.
        The default (False) keeps Embree's float32 distance in the re-centred
        frame (relative error about 1e-7 of the scene's size, far below the
        int16 step) and saves about a tenth of the time.

    Examples
    --------
    >>> import trimesh
    >>> caster = EmbreeCaster(trimesh.creation.box((2, 2, 2)))
    >>> caster.distances(np.zeros(3), np.array([[1.0, 0, 0]])).tolist()
    [1.0]
    """

    def __init__(self, mesh: trimesh.Trimesh, threads: int | None = None, exact: bool = False) -> None:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        if len(mesh.faces) == 0:
            raise LivoxVizError("the scene has no triangles")
        self.mesh = mesh
        self.exact = exact
        self.local_origin = np.asarray(mesh.bounds, dtype=np.float64).mean(axis=0)
        vertices = np.asarray(mesh.vertices, dtype=np.float64)
        faces = np.asarray(mesh.faces, dtype=np.int64)
        self._scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self._scene, (vertices - self.local_origin).astype(np.float32), faces.astype(np.int32))
        # Per-triangle plane in float64: unit normal n and offset n . v0 (world frame).
        v0 = vertices[faces[:, 0]]
        normals = np.cross(vertices[faces[:, 1]] - v0, vertices[faces[:, 2]] - v0)
        lengths = np.linalg.norm(normals, axis=1)
        normals /= np.where(lengths > 0, lengths, 1.0)[:, None]
        # One row per triangle, [nx, ny, nz, n . v0], so a hit needs one gather.
        self._planes = np.column_stack([normals, np.einsum("ij,ij->i", normals, v0)])
        self._workspaces = threading.local()
        self.threads = max(1, threads or usable_cores())
        self._pool = ThreadPoolExecutor(self.threads) if self.threads > 1 else None
        # Embree builds its BVH on the first query; do it now, not inside a timed frame.
        self._scene.run(np.zeros((1, 3), np.float32), np.full((1, 3), 0.57735, np.float32), query="INTERSECT")

    @property
    def takes_float32(self) -> bool:
        """Whether :meth:`distances` of float32 directions are those of the float64 ones they round: true
        unless ``exact`` (which measures along the float64 ones); Embree casts in float32 either way."""
        return not self.exact

    @property
    def face_planes(self) -> np.ndarray:
        """``(F, 4)`` float64 each triangle's unit normal (world frame) and offset ``n . v0``, metres."""
        return self._planes

    def hits(self, origins: np.ndarray, directions: np.ndarray,
             max_distance: float | np.ndarray = np.inf) -> tuple[np.ndarray, np.ndarray]:
        """Distance to each ray's first hit and the triangle it hit.

        Parameters
        ----------
        origins : (n, 3) or (3,) float
            Ray origins, metres, world frame.
        directions : (n, 3) float
            Unit ray directions.
        max_distance : float or (n,) float
            Hits farther than this are misses, metres (per ray or for all).

        Returns
        -------
        distance : (n,) float64
            Metres; ``inf`` for a miss (float32 in the re-centred frame, or float64 from the
            triangle's plane with ``exact``).
        triangle : (n,) int32
            Index of the triangle hit, -1 for a miss.
        """
        origins, directions = _check_rays(origins, directions)
        count = directions.shape[0]
        distance = np.empty(count, dtype=np.float64)
        triangle = np.empty(count, dtype=np.int32)
        if count == 0:
            return distance, triangle
        per_ray = np.ndim(max_distance) > 0
        limits = (np.minimum(np.asarray(max_distance, dtype=np.float64), 1e37) if per_ray
                  else np.float32(min(max_distance, 1e37)))
        local = origins - self.local_origin
        shared_origin = local.shape[0] == 1

        def run(bounds: tuple[int, int]) -> None:
            start, stop = bounds
            rows = stop - start
            part_origins = _part_origins(local, start, stop)
            dists = (np.ascontiguousarray(limits[start:stop], dtype=np.float32) if per_ray
                     else np.full(rows, limits, dtype=np.float32))
            found = self._scene.run(part_origins, np.ascontiguousarray(directions[start:stop], dtype=np.float32),
                                    dists=dists, query="INTERSECT", output=1)
            # Embree reports only hits nearer than the limit; a miss has primID -1.
            ids = found["primID"]
            hit = ids >= 0
            triangle[start:stop] = ids
            far = found["tfar"]
            if self.exact:
                planes = self._planes[np.maximum(ids, 0)]
                o = origins if shared_origin else origins[start:stop]
                with np.errstate(divide="ignore", invalid="ignore"):
                    exact = (planes[:, 3] - np.einsum("ij,ij->i", planes[:, :3], np.broadcast_to(o, (rows, 3)))) / (
                        np.einsum("ij,ij->i", planes[:, :3], directions[start:stop]))
                far = np.where(np.isfinite(exact) & (exact >= 0), exact, far)
            distance[start:stop] = np.where(hit, far, np.inf)

        self._run_split(run, count)
        return distance, triangle

    def occluded(self, origins: np.ndarray, directions: np.ndarray, max_distance: float | np.ndarray) -> np.ndarray:
        """Whether anything lies along each ray closer than its own ``max_distance`` (Embree's occlusion query).

        Parameters
        ----------
        origins : (n, 3) or (3,) float
            Ray origins, metres, world frame.
        directions : (n, 3) float
            Unit ray directions.
        max_distance : float or (n,) float
            Metres, per ray or for all.

        Returns
        -------
        blocked : (n,) bool
        """
        origins, directions = _check_rays(origins, directions)
        count = directions.shape[0]
        blocked = np.zeros(count, dtype=bool)
        limits = np.asarray(max_distance, dtype=np.float64)
        if limits.ndim:
            limits = limits.reshape(count)  # one a ray (an error naming both shapes when it is not)
        shared_origin = origins.shape[0] == 1
        shared_local = origins[0] - self.local_origin if shared_origin else None

        def run(bounds: tuple[int, int]) -> None:
            # The thread's scratch arrays and one compiled pass, as the first-hit queries: the probes of a run, a
            # few hundred rays, spent as long in numpy's conversions as in Embree.
            start, stop = bounds
            work = self._workspace(stop - start)
            part_origins, part_dirs, part_limits = work.rays(None if shared_origin else origins[start:stop],
                                                             shared_local, self.local_origin, directions[start:stop],
                                                             np.float32(0.0))
            np.minimum(limits[start:stop] if limits.ndim else limits, 1e37, out=part_limits, casting="unsafe")
            found = self._scene.run(part_origins, part_dirs, dists=part_limits, query="OCCLUDED")
            blocked[start:stop] = found >= 0

        if count:
            self._run_split(run, count)
        return blocked

    def map_parts(self, function: Callable[[tuple[int, int]], T], count: int, least: int) -> list[T]:
        """``function((start, stop))`` over contiguous parts of ``0..count``, one per worker thread, in order.

        For work that casts rays among other per-ray steps (the return model's): each part runs start to
        finish on one thread, its own casts inside it (:func:`casting_in_this_thread`), so every step uses
        both cores with one hand-over. One part in the calling thread when ``count`` is under twice ``least``
        (its casts in that thread too), when the caster has one thread, or when the calling thread already
        casts inline (a frame cast beside others).
        """
        parts = min(self.threads, count // max(least, 1))
        if self._pool is None or getattr(_this_thread, "inline", False):
            return [function((0, count))]
        if parts < 2:
            # Too short to cut: the part is cast in this thread, its casts too (handing them to the workers cost
            # more than it saved: a datasheet Mid-70 frame 45.5 against 43 ms per second of scan).
            with casting_in_this_thread():
                return [function((0, count))]

        def inline(bounds: tuple[int, int]) -> T:
            with casting_in_this_thread():
                return function(bounds)

        return self._share(inline, [(count * k // parts, count * (k + 1) // parts) for k in range(parts)])

    def _share(self, function: Callable[[tuple[int, int]], T], parts: list[tuple[int, int]]) -> list[T]:
        """``function(part)`` for every part, results in order: the calling thread and ``threads - 1`` workers
        take the parts in turn.

        The caller works instead of waiting: on this kind of machine (virtual CPUs) waking a sleeping worker
        costs about a tenth of a millisecond, as much as splitting a frame's part saves, so one fewer
        wake-up per call is what makes splitting a small call pay.
        """
        if self._pool is None or len(parts) == 1 or getattr(_this_thread, "inline", False):
            return [function(part) for part in parts]
        results: list[T] = [None] * len(parts)  # type: ignore[list-item]
        taken = iter(range(len(parts)))
        lock = threading.Lock()

        def take() -> None:
            while True:
                with lock:
                    k = next(taken, None)
                if k is None:
                    return
                results[k] = function(parts[k])

        helpers = [self._pool.submit(take) for _ in range(min(self.threads, len(parts)) - 1)]
        try:
            take()
        finally:
            for helper in helpers:
                helper.result()
        return results

    def _run_split(self, run: Callable[[tuple[int, int]], object], count: int) -> None:
        """``run((start, stop))`` over contiguous parts of ``0..count``, taken by the calling thread and the
        workers as each comes free.

        Each take is ``1 / (2 threads)`` of the rays left, at most :data:`PART_RAYS` (the scratch arrays stay
        small) and at least :data:`LEAST_RAYS`: large parts while much is left, small ones at the end, so the
        threads finish within a small part of each other. Parts of one size taken in turn left one thread up
        to a whole part behind the other (6 ms of a million rays' 100 ms call); halves, one a thread, leave
        it behind by all the difference in the halves' cost. The caller works instead of waiting for a
        worker to wake (see :meth:`_share`). One thread, or a call under twice :data:`LEAST_RAYS`: parts of
        :data:`PART_RAYS` in turn on the calling thread.
        """
        workers = 0
        if self._pool is not None and not getattr(_this_thread, "inline", False):
            workers = min(self.threads - 1, count // LEAST_RAYS - 1)
        if workers < 1:
            for start in range(0, count, PART_RAYS):
                run((start, min(count, start + PART_RAYS)))
            return
        share = 2 * (workers + 1)
        lock = threading.Lock()
        taken = 0

        def take() -> None:
            nonlocal taken
            while True:
                with lock:
                    start = taken
                    left = count - start
                    if left <= 0:
                        return
                    rows = min(PART_RAYS, max(LEAST_RAYS, left // share))
                    taken = stop = count if left - rows < LEAST_RAYS // 2 else start + rows
                try:
                    run((start, stop))
                except BaseException:
                    with lock:  # the others stop at their next take
                        taken = count
                    raise

        helpers = [self._pool.submit(take) for _ in range(workers)]
        try:
            take()
        finally:
            for helper in helpers:
                helper.result()

    def triangle_ids(self, origins: np.ndarray, directions: np.ndarray, max_distance: float = np.inf) -> np.ndarray:
        """Index of the first triangle each ray hits, ``(n,)`` int32, -1 for a miss."""
        origins, directions = _check_rays(origins, directions)
        ids = np.empty(directions.shape[0], dtype=np.int32)
        self._in_parts(origins, directions, max_distance, ids, None)
        return ids

    def distances(self, origins: np.ndarray, directions: np.ndarray, max_distance: float = np.inf) -> np.ndarray:
        """See :meth:`RayCaster.distances`; ``directions`` may also be float32 (passed to Embree without a copy)."""
        origins, directions = _check_rays(origins, directions)
        distance = np.empty(directions.shape[0], dtype=np.float64)
        self._in_parts(origins, directions, max_distance, None, distance)
        return distance

    def _in_parts(
        self,
        origins: np.ndarray,
        directions: np.ndarray,
        max_distance: float,
        ids: np.ndarray | None,
        distance: np.ndarray | None,
    ) -> None:
        """Cast contiguous parts of the rays on the worker threads, each part start to finish.

        Everything per ray (the origins re-centred and the directions made
        float32, Embree, the misses) runs inside the part, so the threads share
        all the work, not just Embree's; the steps before and after Embree are
        one compiled pass each (:func:`_kernels`), which release the GIL. The
        parts are taken as threads come free and shrink towards the end
        (:meth:`_run_split`), so a thread whose rays were cheap (misses, a near
        wall) takes the next part instead of waiting for the other. Each thread
        has its own scratch arrays, so concurrent calls (frames cast side by
        side) are safe.
        """
        count = directions.shape[0]
        if count == 0:
            return
        limit = np.float32(min(max_distance, 1e37))
        if not limit > 0:  # nothing can be hit within a range of 0
            if ids is not None:
                ids.fill(-1)
            if distance is not None:
                distance.fill(np.inf)
            return
        shared_origin = origins.shape[0] == 1
        shared_local = origins[0] - self.local_origin if shared_origin else None
        plain = distance is not None and not self.exact

        def run(bounds: tuple[int, int]) -> None:
            start, stop = bounds
            work = self._workspace(stop - start)
            part_origins, part_dirs, limits = work.rays(None if shared_origin else origins[start:stop],
                                                        shared_local, self.local_origin, directions[start:stop],
                                                        limit)
            if plain:
                far = self._scene.run(part_origins, part_dirs, dists=limits, query="DISTANCE")
                _KERNELS["misses"](far, limit, distance[start:stop])
                return
            part_ids = self._scene.run(part_origins, part_dirs, dists=limits, query="INTERSECT")
            if ids is not None:
                ids[start:stop] = part_ids
            if distance is not None:
                part_world = origins if shared_origin else origins[start:stop]
                self._plane_distances(part_world, directions[start:stop], part_ids, max_distance, work,
                                      distance[start:stop])

        self._run_split(run, count)

    def _workspace(self, rows: int) -> _Workspace:
        """The calling thread's scratch arrays, ``rows`` long (thread-local: they go when the thread ends)."""
        work = getattr(self._workspaces, "work", None)
        if work is None or work.capacity < rows:
            work = self._workspaces.work = _Workspace(rows)
        return work.sized(rows)

    def _plane_distances(
        self,
        origins: np.ndarray,
        directions: np.ndarray,
        ids: np.ndarray,
        max_distance: float,
        work: _Workspace,
        out: np.ndarray,
    ) -> None:
        """Float64 distance to the plane of each hit triangle; ``inf`` for misses and beyond range.

        Parameters
        ----------
        origins : (n, 3) or (1, 3) float64
        directions : (n, 3) float64
        ids : (n,) int32
            Hit triangles, -1 for a miss.
        work : _Workspace
            Scratch arrays of this part.
        out : (n,) float64
            Where the distances go.
        """
        missed = ids < 0
        face = np.maximum(ids, 0, out=work.faces)
        planes = np.take(self._planes, face, axis=0, out=work.planes)
        # Plain ufuncs on columns, not einsum: they release the GIL, so both parts run at once.
        facing = np.multiply(planes[:, 0], directions[:, 0], out=work.facing)
        for axis in (1, 2):
            facing += np.multiply(planes[:, axis], directions[:, axis], out=work.scratch)
        if origins.shape[0] == 1:
            o = origins[0]
            along = np.multiply(planes[:, 0], o[0], out=out)
            for axis in (1, 2):
                along += np.multiply(planes[:, axis], o[axis], out=work.scratch)
        else:
            along = np.multiply(planes[:, 0], origins[:, 0], out=out)
            for axis in (1, 2):
                along += np.multiply(planes[:, axis], origins[:, axis], out=work.scratch)
        np.subtract(planes[:, 3], along, out=along)
        with np.errstate(divide="ignore", invalid="ignore"):
            exact = np.divide(along, facing, out=out)
        unresolved = ~missed & ~(np.isfinite(exact) & (exact >= 0))
        if np.any(unresolved):
            # A grazing hit the plane cannot resolve keeps Embree's own float32 answer.
            rows = np.flatnonzero(unresolved)
            o = origins if origins.shape[0] == 1 else origins[rows]
            exact[rows] = self._scene.run(
                np.ascontiguousarray(np.broadcast_to(o - self.local_origin, (rows.size, 3)), dtype=np.float32),
                np.ascontiguousarray(directions[rows], dtype=np.float32),
                query="DISTANCE",
            )
        exact[missed | (exact > max_distance)] = np.inf

    def close(self) -> None:
        """Stop the worker threads."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def __del__(self) -> None:
        pool = getattr(self, "_pool", None)
        if pool is not None:
            pool.shutdown(wait=False)


class _Workspace:
    """Scratch arrays of one part of the rays, kept between calls.

    Fresh arrays of a million rays cost more in page faults than the work
    done in them, so each worker part keeps its own and reuses them.

    Parameters
    ----------
    capacity : int
        Rays the arrays hold.
    """

    def __init__(self, capacity: int) -> None:
        self.capacity = capacity
        self._origins = np.empty((capacity, 3), dtype=np.float32)
        self._origin_value: tuple[float, float, float] | None = None
        self._origin_rows = 0  # rows of _origins holding _origin_value
        self._directions = np.empty((capacity, 3), dtype=np.float32)
        self._limits = np.empty(capacity, dtype=np.float32)
        self._faces = np.empty(capacity, dtype=np.int32)
        self._planes = np.empty((capacity, 4), dtype=np.float64)
        self._facing = np.empty(capacity, dtype=np.float64)
        self._scratch = np.empty(capacity, dtype=np.float64)
        self.rows = capacity

    def sized(self, rows: int) -> _Workspace:
        """Use the first ``rows`` rows."""
        self.rows = rows
        return self

    def origins(self, value: np.ndarray) -> np.ndarray:
        """``(rows, 3)`` float32 filled with one origin (filled again only when it changed or more rows are asked)."""
        key = (float(value[0]), float(value[1]), float(value[2]))  # a tuple compares in a fraction of array_equal
        if self._origin_rows < self.rows or key != self._origin_value:
            self._origins[: self.rows] = value
            self._origin_value = key
            self._origin_rows = self.rows
        return self._origins[: self.rows]

    def rays(self, origins: np.ndarray | None, shared: np.ndarray | None, centre: np.ndarray,
             directions: np.ndarray, limit: np.float32) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The part's rays as Embree takes them, in one compiled pass (which releases the GIL once).

        Parameters
        ----------
        origins : (rows, 3) float64 or None
            World origins, one a ray, metres; None for the one origin ``shared``.
        shared : (3,) float64 or None
            The one origin, already less ``centre``, metres.
        centre : (3,) float64
            The scene's own origin (world), metres.
        directions : (rows, 3) float32 or float64
            Unit directions.
        limit : float32
            The rays' initial length, metres.

        Returns
        -------
        origins : (rows, 3) float32
            ``origins - centre`` (the subtraction in float64, then rounded), or ``shared`` repeated.
        directions : (rows, 3) float32
            ``directions`` rounded to float32 (themselves when they already are, contiguous).
        limits : (rows,) float32
            ``limit`` in every row (Embree writes each ray's hit distance over it).
        """
        rows = self.rows
        if origins is None:
            part_origins, origin_values = self.origins(shared), _NOTHING_F64
        else:
            self._origin_rows = 0  # the shared origin's rows are overwritten
            part_origins, origin_values = self._origins[:rows], np.ascontiguousarray(origins).reshape(-1)
        if directions.dtype == np.float32 and directions.flags.c_contiguous:
            part_dirs, direction_values, dirs_out = directions, _NOTHING_F64, _NOTHING_F32
        else:
            part_dirs = self._directions[:rows]
            direction_values, dirs_out = np.ascontiguousarray(directions).reshape(-1), part_dirs.reshape(-1)
        limits = self._limits[:rows]
        _KERNELS["rays"](origin_values, centre, direction_values, part_origins.reshape(-1), dirs_out, limits,
                           limit)
        return part_origins, part_dirs, limits

    @property
    def faces(self) -> np.ndarray:
        """``(rows,)`` int32 scratch."""
        return self._faces[: self.rows]

    @property
    def planes(self) -> np.ndarray:
        """``(rows, 4)`` float64 scratch."""
        return self._planes[: self.rows]

    @property
    def scratch(self) -> np.ndarray:
        """``(rows,)`` float64 scratch."""
        return self._scratch[: self.rows]

    @property
    def facing(self) -> np.ndarray:
        """``(rows,)`` float64 scratch."""
        return self._facing[: self.rows]


def _part_origins(local: np.ndarray, start: int, stop: int) -> np.ndarray:
    """``(stop - start, 3)`` float32 origins of rays ``start:stop``: the one origin repeated, or their own rows."""
    rows = local[0] if local.shape[0] == 1 else local[start:stop]
    return np.ascontiguousarray(np.broadcast_to(rows, (stop - start, 3)), dtype=np.float32)


_NOTHING_F64 = np.empty(0, dtype=np.float64)
_NOTHING_F32 = np.empty(0, dtype=np.float32)
def _rays(origins, centre, directions, origins_out, directions_out, limits, limit):  # pragma: no cover - compiled
    """``limits[:] = limit``; ``origins_out = float32(origins - centre)`` and ``directions_out =
    float32(directions)``, each unless empty.

    Flat arrays: ``origins`` and ``directions`` ``(3 n,)`` float64 (or empty; ``directions`` may be float32),
    ``centre`` ``(3,)`` float64, the outputs ``(3 n,)`` float32 and ``limits`` ``(n,)`` float32. The
    subtraction is in float64, then rounded to nearest, as numpy's ``astype``; no fastmath, so it is the
    same number bit for bit.
    """
    for i in range(limits.shape[0]):
        limits[i] = limit
    for k in range(directions_out.shape[0]):
        directions_out[k] = directions[k]
    if origins.shape[0]:
        c0, c1, c2 = centre[0], centre[1], centre[2]
        for i in range(origins.shape[0] // 3):
            origins_out[3 * i] = origins[3 * i] - c0
            origins_out[3 * i + 1] = origins[3 * i + 1] - c1
            origins_out[3 * i + 2] = origins[3 * i + 2] - c2


def _misses(far, limit, out):  # pragma: no cover - compiled
    """``out = far`` widened to float64 where ``far < limit`` (a hit: Embree shortened the ray), ``inf`` for a
    miss (the ray kept its initial length, ``limit``); NaN stays NaN.

    ``far`` ``(n,)`` float32, ``out`` ``(n,)`` float64 (any stride).
    """
    for i in range(far.shape[0]):
        value = far[i]
        out[i] = value if value < limit or value != value else np.inf


#: The compiled per-ray steps around Embree: ``rays`` (:func:`_rays`) and ``misses`` (:func:`_misses`). numba
#: (``nogil``) imported and the steps compiled, or loaded from numba's cache, on first use: the first cast of a
#: process that has not loaded numba yet takes 0.2-0.4 s and about 110 MiB more. Each step is one pass that
#: releases the GIL once, where numpy took a pass an operation, each casting float64 -> float32 (or bool ->
#: float32 -> float64 for the misses) through its buffers: a million rays from their own origins cost 9.3 ms of
#: CPU before Embree and 4.7 ms after it in numpy, 5.3 ms and 1.4 ms here, of Embree's 180 ms.
_KERNELS = LazyKernels(globals())


class TrimeshCaster:
    """First hits through trimesh's pure-numpy intersector (slow; for cross-checks).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The scene, metres.
    """

    def __init__(self, mesh: trimesh.Trimesh) -> None:
        from trimesh.ray.ray_triangle import RayMeshIntersector

        if len(mesh.faces) == 0:
            raise LivoxVizError("the scene has no triangles")
        self.mesh = mesh
        self._intersector = RayMeshIntersector(mesh)
        normals = np.asarray(mesh.face_normals, dtype=np.float64)
        self._planes = np.column_stack([normals, np.einsum("ij,ij->i", normals, mesh.triangles[:, 0])])

    @property
    def face_planes(self) -> np.ndarray:
        """See :attr:`EmbreeCaster.face_planes`."""
        return self._planes

    def hits(self, origins: np.ndarray, directions: np.ndarray,
             max_distance: float | np.ndarray = np.inf) -> tuple[np.ndarray, np.ndarray]:
        """See :meth:`EmbreeCaster.hits`."""
        origins, directions = _check_rays(origins, directions)
        origins = np.broadcast_to(origins, directions.shape)
        distance = np.full(directions.shape[0], np.inf)
        triangle = np.full(directions.shape[0], -1, dtype=np.int32)
        if directions.shape[0] == 0:
            return distance, triangle
        faces, rays, locations = self._intersector.intersects_id(origins, directions, multiple_hits=False,
                                                                 return_locations=True)
        if len(rays):
            distance[rays] = np.einsum("ij,ij->i", locations - origins[rays], directions[rays])
            triangle[rays] = faces
        far = distance > max_distance
        distance[far], triangle[far] = np.inf, -1
        return distance, triangle

    def occluded(self, origins: np.ndarray, directions: np.ndarray, max_distance: float | np.ndarray) -> np.ndarray:
        """See :meth:`EmbreeCaster.occluded`."""
        distance, _ = self.hits(origins, directions)
        return distance < np.broadcast_to(np.asarray(max_distance, dtype=np.float64), distance.shape)

    def distances(self, origins: np.ndarray, directions: np.ndarray, max_distance: float = np.inf) -> np.ndarray:
        """See :meth:`RayCaster.distances`."""
        origins, directions = _check_rays(origins, directions)
        origins = np.broadcast_to(origins, directions.shape)
        distance = np.full(directions.shape[0], np.inf)
        if directions.shape[0] == 0:
            return distance
        locations, rays, _ = self._intersector.intersects_location(origins, directions, multiple_hits=False)
        if len(rays):
            distance[rays] = np.einsum("ij,ij->i", locations - origins[rays], directions[rays])
        distance[distance > max_distance] = np.inf
        return distance
