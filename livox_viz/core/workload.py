"""The documented budget of one command, checked before any work starts.

A configuration can be valid and still ask for more than a desktop can give
(DataWidth 5000 x DataHeight 2000 x DataCheckFreq 1000 is 10**10 points/s).
Commands check the points they are asked for against :data:`POINT_BUDGET`
(``--force`` lifts it where a user could really want more), and the GUI checks
the points its integration window holds against :data:`WINDOW_BUDGET`; both
refuse with one line that says how much was asked and how much is allowed.

A scene is budgeted the same way, by its triangles (:data:`TRIANGLE_BUDGET`,
:class:`TriangleBudget`), counted before it is built: 40 terrains of a thousand
cells a side are 80 million triangles in a 3 KB file, and each triangle costs
up to about :data:`BYTES_PER_TRIANGLE` to cast into.
"""

from __future__ import annotations

from dataclasses import dataclass

from livox_viz.core.errors import LivoxVizError

#: Points one command may generate, cast or write without ``--force`` (about 17 minutes at 100 000 pts/s).
POINT_BUDGET = 100_000_000
#: Points the GUI's integration window may hold (about 256 MiB of point rings).
WINDOW_BUDGET = 4_000_000
#: The largest count of points anything here computes (``points_before`` saturates there: ``--seconds 1e308`` is
#: this many points, far past every budget, not an integer that overflows). Never a real count.
MOST_POINTS = 2**62
#: Triangles a scene may hold without ``--force`` (about 4 GiB to cast into with the datasheet returns).
TRIANGLE_BUDGET = 4_000_000
#: Memory a triangle of the scene costs a scan, bytes, about: the mesh, Embree's float32 copy and BVH, the
#: per-face planes, materials and parts, and the datasheet model's edge and neighbour tables (measured peak RSS
#: of a 0.1 s scan of a 2-million-triangle terrain less a 200-triangle one's: 260 B with ideal returns, 780 B
#: with the datasheet's; an STL's unshared vertices add a third).
BYTES_PER_TRIANGLE = 1024


def check_points(points: float, what: str, budget: int = POINT_BUDGET, force: bool = False,
                 can_force: bool = True) -> None:
    """Refuse ``points`` above ``budget`` unless ``force``, and less than one point.

    Parameters
    ----------
    points : float
        What the command would make.
    what : str
        The request in the user's words, e.g. ``"scan --seconds 1e9"``.
    budget : int
    force : bool
        The user asked for it anyway.
    can_force : bool
        Whether the command has ``--force`` (the message offers it).
    """
    if not points >= 1:
        raise LivoxVizError(f"{what} holds no point; allowed: at least one point's time (1 / the point rate)")
    if points >= MOST_POINTS:  # a saturated count is no count: say what it means, even with --force
        raise LivoxVizError(f"{what} asks for more points than any run could make (2**62 or more); allowed: at "
                            f"most {budget:,}")
    if points > budget and not force:
        hint = "; pass --force to go on anyway" if budget == POINT_BUDGET and can_force else ""
        raise LivoxVizError(f"{what} asks for {points:,.0f} points; allowed: at most {budget:,}{hint}")


@dataclass
class TriangleBudget:
    """The triangles of a scene counted as it is read, refused before the one that passes :data:`TRIANGLE_BUDGET`.

    Parameters
    ----------
    force : bool
        The user asked for more anyway (``--force``): nothing is refused.
    can_force : bool
        Whether the command has ``--force`` (the message offers it).
    count : int
        Triangles counted so far.
    """

    force: bool = False
    can_force: bool = False
    count: int = 0

    def check(self, triangles: int, what: str) -> None:
        """Refuse ``what`` if the scene with ``triangles`` more (not counted yet) would pass the budget."""
        total = self.count + int(triangles)
        if total > TRIANGLE_BUDGET and not self.force:
            gib = total * BYTES_PER_TRIANGLE / 2**30
            others = f" (with the {self.count:,} before it)" if self.count else ""
            raise LivoxVizError(f"{what} holds {int(triangles):,} triangles{others}, about {gib:,.1f} GiB to cast "
                                f"into; allowed: at most {TRIANGLE_BUDGET:,} in a scene"
                                + ("; pass --force to go on anyway" if self.can_force else ""))

    def add(self, triangles: int, what: str) -> None:
        """:meth:`check`, then count them."""
        self.check(triangles, what)
        self.count += int(triangles)
