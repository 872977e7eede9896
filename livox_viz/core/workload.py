"""The documented budget of one command, checked before any work starts.

A configuration can be valid and still ask for more than a desktop can give
(DataWidth 5000 x DataHeight 2000 x DataCheckFreq 1000 is 10**10 points/s).
Commands check the points they are asked for against :data:`POINT_BUDGET`
(``--force`` lifts it where a user could really want more), and the GUI checks
the points its integration window holds against :data:`WINDOW_BUDGET`; both
refuse with one line that says how much was asked and how much is allowed.
"""

from __future__ import annotations

from livox_viz.core.errors import LivoxVizError

#: Points one command may generate, cast or write without ``--force`` (about 17 minutes at 100 000 pts/s).
POINT_BUDGET = 100_000_000
#: Points the GUI's integration window may hold (about 256 MiB of point rings).
WINDOW_BUDGET = 4_000_000


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
    if points > budget and not force:
        hint = "; pass --force to go on anyway" if budget == POINT_BUDGET and can_force else ""
        raise LivoxVizError(f"{what} asks for {points:,.0f} points; allowed: at most {budget:,}{hint}")
