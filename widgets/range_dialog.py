"""View > Colour range...: the dialog where the scene colour bar's min and max are typed (ParaView's "Rescale to
custom range"), with Automatic to give the bar the data's range back. It only asks: the window checks what was
typed (:func:`~livox_viz.widgets.colour_range.parse_colour_range`) and asks again, saying why, when it is refused.
"""

from __future__ import annotations

from qtpy import QtWidgets

#: What :meth:`ColourRangeDialog.ask` gives for the Automatic button.
AUTOMATIC = "automatic"


class ColourRangeDialog(QtWidgets.QDialog):
    """Two boxes (min, max), a line saying why the last pair was refused, and Apply, Automatic and Cancel.

    Parameters
    ----------
    parent : QWidget
    mode : str
        The scene colouring whose range it is.
    unit : str
        Its numbers' unit ("" for none).
    values : (str, str)
        The min and max the boxes start with.
    data_range : (float, float)
        The data's range now (what Automatic gives), said in the dialog.
    note : str
        Why the last pair was refused ("" for none), shown in red.
    """

    def __init__(self, parent: QtWidgets.QWidget, mode: str, unit: str, values: tuple[str, str],
                 data_range: tuple[float, float], note: str = "") -> None:
        super().__init__(parent)
        self.setObjectName("colour-range")
        in_unit = f" ({unit})" if unit else ""
        self.setWindowTitle(f"Colour range of the {mode} colouring")
        layout = QtWidgets.QVBoxLayout(self)
        form = QtWidgets.QFormLayout()
        self.low, self.high = QtWidgets.QLineEdit(values[0]), QtWidgets.QLineEdit(values[1])
        self.low.setObjectName("colour-range-min")
        self.high.setObjectName("colour-range-max")
        form.addRow(f"min{in_unit}:", self.low)
        form.addRow(f"max{in_unit}:", self.high)
        layout.addLayout(form)
        spaced = f" {unit}" if unit else ""
        words = QtWidgets.QLabel(f"Points below min take the colour map's first colour, above max its last. "
                                 f"Automatic: the data's range ({data_range[0]:g} to {data_range[1]:g}{spaced} now).")
        words.setWordWrap(True)
        layout.addWidget(words)
        self.note = QtWidgets.QLabel(note)
        self.note.setObjectName("colour-range-refusal")
        self.note.setWordWrap(True)
        self.note.setStyleSheet("color: #d9534f;")
        self.note.setVisible(bool(note))
        layout.addWidget(self.note)
        buttons = QtWidgets.QDialogButtonBox(self)
        apply = buttons.addButton("Apply", QtWidgets.QDialogButtonBox.ButtonRole.AcceptRole)
        apply.setDefault(True)
        self.automatic = buttons.addButton("Automatic", QtWidgets.QDialogButtonBox.ButtonRole.ResetRole)
        buttons.addButton(QtWidgets.QDialogButtonBox.StandardButton.Cancel)
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        self.chose_automatic = False
        self.automatic.clicked.connect(self._automatic)
        layout.addWidget(buttons)
        self.resize(max(self.sizeHint().width(), 420), self.sizeHint().height())
        self.low.selectAll()

    def _automatic(self) -> None:
        self.chose_automatic = True
        self.accept()

    @classmethod
    def ask(cls, parent: QtWidgets.QWidget, mode: str, unit: str, values: tuple[str, str],
            data_range: tuple[float, float], note: str = "") -> tuple[str, str] | str | None:
        """Show the dialog and wait: the two texts typed (Apply), :data:`AUTOMATIC`, or None (Cancel)."""
        dialog = cls(parent, mode, unit, values, data_range, note)
        try:
            if not dialog.exec():
                return None
            return AUTOMATIC if dialog.chose_automatic else (dialog.low.text(), dialog.high.text())
        finally:
            dialog.deleteLater()
