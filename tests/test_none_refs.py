"""None's reference count in the window's process (Python 3.11, where None is not yet immortal).

PySide6 6.12.0 took a reference off None in every call of a method that returns nothing; the window died within
minutes with "Fatal Python error: none_dealloc: deallocating None". These tests need no display: a QObject
works without an application.
"""

from __future__ import annotations

import ctypes
import sys

import pytest

pytest.importorskip("qtpy")

#: ``Py_DecRef`` with its argument passed as the object (as a binding that forgets a reference does).
_decref = ctypes.PYFUNCTYPE(None, ctypes.py_object)(("Py_DecRef", ctypes.pythonapi))


def test_the_installed_qt_binding_keeps_none_alive() -> None:
    """A thousand calls of a method that returns nothing leave None's count where it was (PySide6 6.12.0 on
    Python 3.11 took a thousand: ``pyproject.toml`` keeps it out)."""
    import PySide6
    from qtpy import QtCore

    probe = QtCore.QObject()
    probe.setObjectName("probe")
    before = sys.getrefcount(None)
    for _ in range(1000):
        probe.setObjectName("probe")
        probe.blockSignals(False)  # returns a bool: a sound reference, for contrast
    lost = before - sys.getrefcount(None)
    assert lost < 50, f"PySide6 {PySide6.__version__} took {lost} references off None in 1000 calls"


def test_the_reserve_gives_none_back_what_it_lost() -> None:
    from livox_viz.widgets.nonerefs import NoneReserve

    reserve = NoneReserve()
    for _ in range(5000):
        _decref(None)
    assert reserve.top_up() >= 5000 or sys.version_info >= (3, 12)
    assert sys.getrefcount(None) >= reserve.floor
    assert reserve.top_up() == 0  # nothing lost since


@pytest.mark.skipif(sys.version_info >= (3, 12), reason="None is immortal from Python 3.12: the probe never arms")
def test_the_probe_tells_a_binding_that_drops_none_from_a_sound_one(monkeypatch: pytest.MonkeyPatch) -> None:
    from livox_viz.widgets.nonerefs import binding_drops_none
    from qtpy import QtCore

    assert not binding_drops_none()  # the binding installed (see the test above)

    class DropsNone(QtCore.QObject):
        def setObjectName(self, name: str) -> None:
            super().setObjectName(name)
            _decref(None)

    monkeypatch.setattr(QtCore, "QObject", DropsNone)
    assert binding_drops_none()
