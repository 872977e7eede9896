"""The Picks panel: a dock listing the scene view's picks with their coordinates, and what the last ones measure.

CloudCompare's point list picking and ParaView's spreadsheet of a selection: one row per pick (its number, as
beside its dot in the view, x, y, z in the world frame the cloud is drawn in, range, angles, reflectivity,
time), the distance and angles of the last picks in its footer, and Copy (tab-separated with a header: it
pastes into a spreadsheet), Remove last and Clear. The rows and the words are made by
:mod:`~livox_viz.widgets.picks`; the panel shows what the controller holds and asks it for every change, as
the parameter panel does.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from qtpy import QtCore, QtGui, QtWidgets

from .app import LivoxVizApp
from .picks import COLUMNS, FRAME_NOTE, measures_text, pick_cells, pick_measures, picks_tsv

#: What the footer says before there is anything to measure.
FOOTER_HINT = ("click a point of the cloud to pick it; a second gives the distance and the angle between their "
               "rays, a third the angle at the middle one")
#: Tooltips of the columns' headers.
COLUMN_TIPS = {
    "number": "the pick's number, as beside its dot in the scene view",
    "x": "world x, north, metres (NED, as the PLY, PCD and CSV exports)",
    "y": "world y, east, metres (NED)",
    "z": "world z, down, metres (NED: a point above the ground has a negative z)",
    "range_m": "distance from the sensor, metres, as the sensor measured it (decoded)",
    "azimuth_deg": "angle to the sensor's right of its boresight, degrees",
    "elevation_deg": "angle above the sensor's boresight, degrees",
    "reflectivity": "the return's reflectivity byte (0 with ideal returns)",
    "t_s": "the firing's scan time, seconds",
}
#: The keys a focused list keeps from the window's shortcuts (moving its selection): the rest stay the window's.
_LIST_KEYS = frozenset({QtCore.Qt.Key.Key_Up, QtCore.Qt.Key.Key_Down, QtCore.Qt.Key.Key_Left, QtCore.Qt.Key.Key_Right,
                        QtCore.Qt.Key.Key_PageUp, QtCore.Qt.Key.Key_PageDown, QtCore.Qt.Key.Key_Home,
                        QtCore.Qt.Key.Key_End})


class _KeepListKeys(QtCore.QObject):
    """Up and Down move the focused list's selection, not the playback speed (Right, the window's step, too)."""

    def eventFilter(self, watched: QtCore.QObject, event: QtCore.QEvent) -> bool:
        if event.type() == QtCore.QEvent.Type.ShortcutOverride and QtCore.Qt.Key(event.key()) in _LIST_KEYS \
                and event.modifiers() == QtCore.Qt.KeyboardModifier.NoModifier:
            event.accept()
        return False


#: One filter for every list, owned by no widget, as the parameter panel's (panel.keep_keys): nothing of it goes
#: with a window's widget tree when that is destroyed.
_LIST_KEYS_FILTER: _KeepListKeys | None = None


def _keep_list_keys(widget: QtWidgets.QWidget) -> None:
    global _LIST_KEYS_FILTER
    if _LIST_KEYS_FILTER is None:
        _LIST_KEYS_FILTER = _KeepListKeys()
    widget.installEventFilter(_LIST_KEYS_FILTER)


class PicksPanel(QtWidgets.QDockWidget):
    """The dock (View > Picks); it opens at the first pick of a list.

    Parameters
    ----------
    controller : LivoxVizApp
        Holds the picks (:attr:`~livox_viz.widgets.app.LivoxVizApp.picks`) and changes them.
    run : callable
        ``run(action)``: the window's way to run an action (a refusal becomes a line in the status bar).
    parent : QWidget, optional
    """

    def __init__(self, controller: LivoxVizApp, run: Callable[[Callable[[], Any]], None],
                 parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__("Picks", parent)
        self.setObjectName("picks")
        self.controller = controller
        self._run = run
        self.setFeatures(QtWidgets.QDockWidget.DockWidgetFeature.DockWidgetMovable
                         | QtWidgets.QDockWidget.DockWidgetFeature.DockWidgetFloatable
                         | QtWidgets.QDockWidget.DockWidgetFeature.DockWidgetClosable)
        content = QtWidgets.QWidget(self)
        layout = QtWidgets.QVBoxLayout(content)
        layout.setContentsMargins(6, 4, 6, 4)
        layout.setSpacing(4)

        top = QtWidgets.QHBoxLayout()
        self.note = QtWidgets.QLabel(FRAME_NOTE)
        self.note.setObjectName("picks-frame")
        self.note.setWordWrap(True)
        top.addWidget(self.note, 1)
        # Ctrl+C with the list (or any of the panel) focused copies, as the button does.
        self.copy_action = QtGui.QAction("Copy", self)
        self.copy_action.setShortcut(QtGui.QKeySequence(QtGui.QKeySequence.StandardKey.Copy))
        self.copy_action.setShortcutContext(QtCore.Qt.ShortcutContext.WidgetWithChildrenShortcut)
        self.copy_action.setToolTip("copy the selected picks (all when none is selected) as tab-separated text with "
                                    "a header, to paste into a spreadsheet (Ctrl+C)")
        self.copy_action.triggered.connect(lambda _checked=False: self._run(self.copy))
        self.addAction(self.copy_action)
        self.buttons: dict[str, QtWidgets.QToolButton] = {}
        for name, action in (("Copy", None), ("Remove last", controller.remove_last_pick),
                             ("Clear", controller.clear_picks),
                             ("Turn about last", controller.turn_about_last_pick)):
            button = QtWidgets.QToolButton(content)
            if action is None:
                button.setDefaultAction(self.copy_action)
            else:
                button.setText(name)
                button.clicked.connect(lambda _checked=False, a=action: self._run(a))
            button.setToolButtonStyle(QtCore.Qt.ToolButtonStyle.ToolButtonTextOnly)
            self.buttons[name] = button
            top.addWidget(button)
        self.buttons["Remove last"].setToolTip("take the last pick and its mark away")
        self.buttons["Clear"].setToolTip("take every pick and its mark away")
        self.buttons["Turn about last"].setToolTip("the scene camera turns about the last pick (View menu; r resets "
                                                   "the cameras)")
        layout.addLayout(top)

        self.table = QtWidgets.QTableWidget(0, len(COLUMNS), content)
        self.table.setObjectName("picks-table")
        self.table.setEditTriggers(QtWidgets.QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.setSelectionBehavior(QtWidgets.QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setAlternatingRowColors(True)
        self.table.verticalHeader().setVisible(False)
        self.table.verticalHeader().setDefaultSectionSize(self.table.fontMetrics().height() + 6)
        header = self.table.horizontalHeader()
        header.setSectionResizeMode(QtWidgets.QHeaderView.ResizeMode.ResizeToContents)
        header.setStretchLastSection(False)
        for column, (key, title, _, _) in enumerate(COLUMNS):
            item = QtWidgets.QTableWidgetItem(title)
            item.setToolTip(COLUMN_TIPS[key])
            self.table.setHorizontalHeaderItem(column, item)
        self.table.setMinimumHeight(self.table.horizontalHeader().sizeHint().height() + 2 * (
            self.table.verticalHeader().defaultSectionSize()) + 6)
        _keep_list_keys(self.table)
        # A row clicked (or moved to with the arrows) rings its pick's dot in the scene view. After the event in
        # hand: the selection also changes inside another action (a pick, Clear), which must not run one nested.
        self.table.itemSelectionChanged.connect(
            lambda: QtCore.QTimer.singleShot(0, self, lambda: self._run(self._select)))
        layout.addWidget(self.table, 1)

        self.footer = QtWidgets.QLabel(FOOTER_HINT)
        self.footer.setObjectName("picks-measures")
        self.footer.setWordWrap(True)
        self.footer.setTextInteractionFlags(QtCore.Qt.TextInteractionFlag.TextSelectableByMouse)
        layout.addWidget(self.footer)
        self.setWidget(content)
        self.follow()

    def follow(self) -> None:
        """Show the controller's picks: one row each, and the measures of the last ones in the footer."""
        picks = self.controller.picks
        table = self.table
        table.setRowCount(len(picks))
        for row, pick in enumerate(picks):
            for column, text in enumerate(pick_cells(row + 1, pick)):
                item = table.item(row, column)
                if item is None:
                    item = QtWidgets.QTableWidgetItem()
                    item.setTextAlignment(QtCore.Qt.AlignmentFlag.AlignRight | QtCore.Qt.AlignmentFlag.AlignVCenter)
                    table.setItem(row, column, item)
                item.setText(text)
        if picks:
            table.scrollToBottom()
        measured = measures_text(pick_measures(picks))
        if measured:
            self.footer.setText(f"pick {len(picks)}: {measured}")
        else:
            self.footer.setText(f"pick 1; {FOOTER_HINT.split('; ', 1)[1]}" if picks else FOOTER_HINT)
        for name in ("Remove last", "Clear", "Turn about last"):
            self.buttons[name].setEnabled(bool(picks))
        self.copy_action.setEnabled(bool(picks))

    def _select(self) -> None:
        rows = sorted({index.row() for index in self.table.selectionModel().selectedRows()})
        self.controller.select_picks([row for row in rows if row < len(self.controller.picks)])

    def copy(self) -> None:
        """Put the selected picks (all when none is) on the clipboard as tab-separated text with a header."""
        picks = self.controller.picks
        if not picks:
            self.controller.session.message = "no picks to copy: click a point of the cloud first"
            return
        rows = sorted({index.row() for index in self.table.selectionModel().selectedRows()}) or None
        QtWidgets.QApplication.clipboard().setText(picks_tsv(picks, rows))
        count = len(picks) if rows is None else len(rows)
        self.controller.session.message = (f"copied {count} pick{'s' if count != 1 else ''} to the clipboard "
                                           "(tab-separated, with a header)")
