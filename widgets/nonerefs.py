"""A guard against a Qt binding that drops references to None.

Up to Python 3.11 None is reference counted like any object, and a C extension must add a reference to None
before it returns it. PySide6 6.12.0 does not in its methods that return nothing: every ``label.setText(...)``,
``action.setChecked(...)``, ``widget.update()`` takes one reference off None. The window makes some 20 such
calls per tick and more per action, so None's count (about 100 000 once VTK, pyvista and numba are imported)
reached zero within minutes and the process died with "Fatal Python error: none_dealloc: deallocating None",
in whichever call took the last reference (a first-use trial saw it in the status bar's update).

``pyproject.toml`` keeps PySide6 below 6.12 on Python 3.11; this guard covers a binding installed by other means
(a user's ``pip install -U PySide6``, another distribution): the window probes the binding once and, when it
drops references, gives None back each tick what it lost, so the count never reaches zero. From Python 3.12 on
None is immortal (PEP 683): its count does not move and the guard is never armed.
"""

from __future__ import annotations

import ctypes
import sys

#: Calls of a method that returns nothing the probe makes; a binding that drops a reference in each loses them all.
PROBE_CALLS = 200

#: ``Py_IncRef`` of the C API with its argument passed as the object itself (ctypes' default would pass None as NULL).
_incref = ctypes.PYFUNCTYPE(None, ctypes.py_object)(("Py_IncRef", ctypes.pythonapi))


def binding_drops_none(calls: int = PROBE_CALLS) -> bool:
    """True when the Qt binding takes a reference off None in a call of a method that returns nothing.

    Parameters
    ----------
    calls : int
        How many calls the probe makes (``QObject.setObjectName``); half of them lost counts as dropping.
    """
    if sys.version_info >= (3, 12):  # None is immortal: nothing to lose
        return False
    from qtpy import QtCore

    probe = QtCore.QObject()
    probe.setObjectName("livox-viz-probe")  # a first call may allocate the name once
    before = sys.getrefcount(None)
    for _ in range(calls):
        probe.setObjectName("livox-viz-probe")
    return before - sys.getrefcount(None) >= calls // 2


class NoneReserve:
    """Keeps None's reference count from falling below where it was when made.

    Attributes
    ----------
    floor : int
        None's count when the reserve was made.
    given : int
        References given back to None so far (those the binding took).
    """

    def __init__(self) -> None:
        self.floor = sys.getrefcount(None)
        self.given = 0

    def top_up(self) -> int:
        """Give None the references it lost since the floor was taken; the number given (0 when none were lost).

        A reference given is never taken back: None is never freed, so a count kept higher than needed costs
        nothing, while one that reaches zero ends the process.
        """
        missing = self.floor - sys.getrefcount(None)
        for _ in range(missing):
            _incref(None)
        if missing > 0:
            self.given += missing
        return max(0, missing)
