"""View > Filters...: the scene view's range and reflectivity bounds typed into a small dialog beside the window.

Not modal: the cloud changes behind it as bounds are applied, as in
CloudCompare's "Filter by value". The bounds are checked by
:class:`~livox_viz.widgets.filters.CloudFilter`; a refusal is one line, in
the dialog and in the window's status bar, and the filter drawn stays as it
was.
"""

from __future__ import annotations

from collections.abc import Callable

from qtpy import QtCore, QtGui, QtWidgets

from livox_viz.core.errors import LivoxVizError

from .filters import REFLECTIVITY_LIMITS, CloudFilter
from .panel import TypedTextError, number_text, read_typed

#: The note's colour when it says a refusal (the status bar's red).
REFUSED_COLOUR = "#d9534f"
#: The dialog's width, as its wrapped words are: room for a refusal on two lines.
INTRO_WIDTH_PX = 440


class FilterDialog(QtWidgets.QDialog):
    """Four boxes (range min and max in metres, reflectivity min and max), Apply, Clear and Close.

    Parameters
    ----------
    parent : QWidget
    current : callable
        The filter drawn now.
    apply : callable
        ``apply(cloud_filter)`` draws it (None: no filter); returns the refusal's line, or None when it was taken.
    refuse : callable
        ``refuse(line)`` says a refusal made here in the window's status bar, as its other refusals are.
    """

    def __init__(self, parent: QtWidgets.QWidget, current: Callable[[], CloudFilter],
                 apply: Callable[[CloudFilter | None], str | None], refuse: Callable[[str], None]) -> None:
        super().__init__(parent)
        self.setObjectName("filters")
        self.setWindowTitle("livox-viz - scene filters")
        self._current = current
        self._apply = apply
        self._refuse = refuse
        low, high = REFLECTIVITY_LIMITS
        self.boxes: dict[str, QtWidgets.QLineEdit] = {}
        form = QtWidgets.QFormLayout()
        for title, (first, second), tip in (
                ("Range, m", ("range_min_m", "range_max_m"),
                 "the range each point was measured at, metres; empty: no bound on that side"),
                (f"Reflectivity, {low}-{high}", ("reflectivity_min", "reflectivity_max"),
                 "the Livox reflectivity byte (0-150 diffuse, 151-255 retroreflective); ideal returns carry 0")):
            row = QtWidgets.QHBoxLayout()
            for key, side in ((first, "min"), (second, "max")):
                box = QtWidgets.QLineEdit()
                box.setObjectName(key)
                box.setPlaceholderText(f"{side}: none")
                box.setToolTip(tip)
                box.returnPressed.connect(self.apply_typed)
                self.boxes[key] = box
                row.addWidget(box)
                if side == "min":
                    row.addWidget(QtWidgets.QLabel("to"))
            form.addRow(title, row)
        self.note = QtWidgets.QLabel()
        self.note.setObjectName("note")
        self.note.setWordWrap(True)
        buttons = QtWidgets.QDialogButtonBox()
        self.apply_button = buttons.addButton("Apply", QtWidgets.QDialogButtonBox.ButtonRole.ApplyRole)
        self.clear_button = buttons.addButton("Clear filters", QtWidgets.QDialogButtonBox.ButtonRole.ResetRole)
        close = buttons.addButton(QtWidgets.QDialogButtonBox.StandardButton.Close)
        self.apply_button.clicked.connect(self.apply_typed)
        self.clear_button.clicked.connect(self.clear)
        close.clicked.connect(self.hide)
        for button in (self.apply_button, self.clear_button, close):
            button.setAutoDefault(False)  # Enter in a box applies once, through the box (keyPressEvent)
        layout = QtWidgets.QVBoxLayout(self)
        intro = QtWidgets.QLabel("The scene view draws only the points inside these bounds (both included); the "
                                 "others are hidden and cannot be picked. The scan, its exports and the charts "
                                 "keep every point.")
        intro.setWordWrap(True)
        layout.addWidget(intro)
        layout.addLayout(form)
        layout.addWidget(self.note)
        layout.addWidget(buttons)
        # Sized by its layout, word-wrapped lines' heights included, whenever its note changes: a dialog sized once
        # cut the intro's last line off, and a longer refusal would have been cut too.
        layout.setSizeConstraint(QtWidgets.QLayout.SizeConstraint.SetFixedSize)
        intro.setFixedWidth(INTRO_WIDTH_PX)

    def show_current(self) -> None:
        """Fill the boxes from the filter drawn now and say it."""
        current = self._current()
        for key, value in current.to_json().items():
            self.boxes[key].setText("" if value is None else number_text(float(value)))
        self._say(f"drawn now: {current.describe()}" if current.active else "drawn now: every point (no filter)")

    def apply_typed(self) -> None:
        """The bounds typed, checked, drawn; a refusal said here and in the status bar, the filter drawn kept."""
        try:
            values = {}
            for key, box in self.boxes.items():
                text = box.text().strip()
                if not text:
                    values[key] = None
                    continue
                whole = key.startswith("reflectivity")
                value = read_typed(text, "" if whole else "m", whole)
                values[key] = int(value) if whole and value.is_integer() else value
            cloud_filter = CloudFilter(**values)
        except (TypedTextError, LivoxVizError) as exc:
            self._say(str(exc), refused=True)
            self._refuse(f"filters: {exc}")
            return
        refused = self._apply(cloud_filter)
        if refused:
            self._say(refused, refused=True)
            return
        self.show_current()

    def clear(self) -> None:
        """Every point drawn again; the boxes emptied."""
        self._apply(None)
        self.show_current()

    def _say(self, text: str, refused: bool = False) -> None:
        self.note.setText(text)
        self.note.setStyleSheet(f"color: {REFUSED_COLOUR};" if refused else "")

    def keyPressEvent(self, event: QtGui.QKeyEvent) -> None:
        # Enter in a box applies (returnPressed); it must not also press the dialog's default button and close it.
        if event.key() in (QtCore.Qt.Key.Key_Return, QtCore.Qt.Key.Key_Enter):
            event.accept()
            return
        super().keyPressEvent(event)
