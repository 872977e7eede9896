"""The parameter panel: a slider and a spin box for every tunable parameter, built from the model's own table.

Each row is made from :data:`~livox_viz.config.sensor.PARAM_RANGES` (the
allowed range, the same the command line validates) and
:mod:`livox_viz.config.param_docs` (title, unit, steps, what the parameter does):
a slider over the allowed range (log scale where the range spans decades), a
spin box taking a typed value, the unit, and a button that resets the value to
the preset's. Arrow keys and the wheel step by the parameter's step, by a tenth
of it with Shift or Ctrl held.

Values flow one way, as in napari's layer controls: a control asks the
controller for the new value (:meth:`~livox_viz.widgets.app.LivoxVizApp.on_param`),
the session validates it, and the panel shows what the session holds, with
its signals blocked while it sets its own controls so nothing feeds back. A
typed value outside the range is refused in the control (its allowed range is
shown beside it and in the status bar); the scan goes on with the old value.

The panel is rebuilt from scratch whenever the set of its rows changes
(another pattern model, preset, page or return model): every widget of the old
state is deleted with it, so nothing is left over and nothing overlaps.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from qtpy import QtCore, QtGui, QtWidgets

from livox_viz.config.param_docs import describe, param_doc, slider_fraction, slider_value, value_bounds
from livox_viz.config.sensor import PARAM_RANGES, SensorConfig
from livox_viz.core.errors import LivoxVizError

from .controls import PATTERN_PARAMS, RETURN_PARAMS, frame_params
from .overlay import WINDOWS
from .playback import SPEED_RANGE
from .session import WINDOW_RANGE

#: Slider positions across a parameter's range.
SLIDER_STEPS = 1000
#: A drag with Shift or Ctrl held moves the value this many times slower than the handle.
FINE_DRAG = 10
#: While a slider is dragged, the scan follows at most this often (ms): each change restarts the pattern.
LIVE_DRAG_MS = 120
_MODEL_TITLES = {"rflysim": "Pattern: RflySim rosette (otherParams)", "risley": "Pattern: Risley prisms",
                 "track": "Pattern: track"}


@contextmanager
def signals_blocked(*widgets: QtCore.QObject) -> Iterator[None]:
    """Block the widgets' signals while the panel sets them itself (napari's ``qt_signals_blocked``)."""
    previous = [widget.blockSignals(True) for widget in widgets]
    try:
        yield
    finally:
        for widget, was in zip(widgets, previous, strict=True):
            widget.blockSignals(was)


class KeepKeys(QtCore.QObject):
    """Keeps the keys a focused control uses for itself (arrows, pages, digits, letters, space) from the window's
    shortcuts: Up in a spin box steps its value, it does not double the playback speed."""

    _NAVIGATION = frozenset({
        QtCore.Qt.Key.Key_Up, QtCore.Qt.Key.Key_Down, QtCore.Qt.Key.Key_Left, QtCore.Qt.Key.Key_Right,
        QtCore.Qt.Key.Key_PageUp, QtCore.Qt.Key.Key_PageDown, QtCore.Qt.Key.Key_Home, QtCore.Qt.Key.Key_End,
        QtCore.Qt.Key.Key_Space})

    def eventFilter(self, watched: QtCore.QObject, event: QtCore.QEvent) -> bool:
        if event.type() == QtCore.QEvent.Type.ShortcutOverride:
            key = QtCore.Qt.Key(event.key())
            if key in self._NAVIGATION or (event.text() and event.text().isprintable()):
                event.accept()
        return False


_KEEP_KEYS: KeepKeys | None = None


def keep_keys(*widgets: QtWidgets.QWidget) -> None:
    """Let each of ``widgets`` keep its own keys while it has the focus (:class:`KeepKeys`)."""
    global _KEEP_KEYS
    if _KEEP_KEYS is None:
        _KEEP_KEYS = KeepKeys()
    for widget in widgets:
        widget.installEventFilter(_KEEP_KEYS)


def _fine(modifiers: QtCore.Qt.KeyboardModifier) -> bool:
    wanted = QtCore.Qt.KeyboardModifier.ShiftModifier | QtCore.Qt.KeyboardModifier.ControlModifier
    return bool(modifiers & wanted)


#: A number as a user types it: digits with an optional point and an optional exponent (``12``, ``.5``,
#: ``2.5E-3``, ``1e1``); no group separators, no ``inf`` or ``nan``.
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


class TypedTextError(ValueError):
    """Typed text that is not a number of the box's unit: the message says what was wrong and what is taken."""


def read_typed(text: str, unit: str, whole: bool = False) -> float:
    """The number ``text`` holds: a plain or scientific number, optionally followed by ``unit`` (``whole``: the
    parameter takes whole numbers, and the refusal's examples are whole).

    Raises
    ------
    TypedTextError
        Anything else (another unit, words, a comma), with what is taken instead.
    """
    body = text.strip()
    if unit and body.endswith(unit):
        body = body[: -len(unit)].rstrip()
    if _NUMBER.fullmatch(body):
        return float(body)
    in_unit = f" in {unit}" if unit else ""
    examples = "12 or 1e2" if whole else "12, 2.5 or 1e1"
    kind = "a whole number" if whole else "a number"
    raise TypedTextError(f"'{text.strip()}' refused: only {kind}{in_unit} is taken (as {examples})")


#: Decimals a value box holds and shows at most: enough for any value a user types (12 significant digits of a
#: value near 100), with the zeros after the last one left out.
HELD_DECIMALS = 10
#: Significant digits a value box shows at most.
SHOWN_DIGITS = 9


def number_text(value: float) -> str:
    """``value`` as a value box and the heads-up text show it: plain digits, as many decimals as it has (to
    :data:`HELD_DECIMALS`, and :data:`SHOWN_DIGITS` significant digits), never ``1.095e+04``. A box that showed
    its parameter's three decimals showed 180 for a typed 179.9999 that the scan used, while 180 itself was refused
    (issue 45)."""
    # Nine significant digits at most: a fitted preset's 4663.99999998 rpm showed its float noise and cut its unit
    # off (4664 is what it is, to 2e-8).
    magnitude = math.floor(math.log10(abs(value))) if value else 0
    decimals = max(0, min(HELD_DECIMALS, SHOWN_DIGITS - 1 - magnitude))
    text = f"{value:.{decimals}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text == "-0" else text


def wheel_is_for_the_panel(control: QtWidgets.QWidget, event: QtGui.QWheelEvent) -> bool:
    """True (and the event left to the panel, which scrolls) when ``control`` has not the keyboard focus.

    A first-use trial rolled the wheel to scroll the parameter panel: whichever slider or box came under the
    cursor took the notches (DataWidth 250 to 116, the scan restarted, no word). As in Qt Creator, Blender and
    ParaView, a control takes the wheel only once clicked or tabbed into.
    """
    if control.hasFocus():
        return False
    event.ignore()
    return True


class NoWheelUnlessFocused(QtWidgets.QComboBox):
    """A combo box that leaves the wheel to the panel unless it has the focus (see :func:`wheel_is_for_the_panel`)."""

    def __init__(self, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self.setFocusPolicy(QtCore.Qt.FocusPolicy.StrongFocus)

    def wheelEvent(self, event: QtGui.QWheelEvent) -> None:
        if not wheel_is_for_the_panel(self, event):
            super().wheelEvent(event)


class ValueBox(QtWidgets.QDoubleSpinBox):
    """A spin box that takes any typed number and leaves judging it to the model (the range is shown, not clamped
    silently); arrows and the wheel step by ``step``, by ``fine_step`` with Shift or Ctrl, within ``bounds``.

    Qt's own reading of typed text drops what it does not know keystroke by keystroke (``1e1`` became ``11``,
    ``45 rad`` became ``45``) and rounds to the decimals shown: here the box lets every keystroke in and reads
    the text once, on Enter or when the focus leaves, with :func:`read_typed`; :meth:`take_typed` hands the
    number (exact) or the refusal to whoever commits it, and the box itself never changes on typed text.
    """

    def __init__(self, bounds: tuple[float, float], decimals: int, step: float, fine_step: float,
                 unit: str, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self.bounds = bounds
        self.step = step
        self.fine_step = fine_step
        # The box holds every decimal a typed value has (Qt rounds what it holds to the decimals set): what it shows
        # is what the scan uses. ``decimals`` is the parameter's usual precision, kept for callers.
        self.shown_decimals = decimals
        self.setDecimals(HELD_DECIMALS)
        # Wide enough to type any number: a value outside the allowed range is refused on commit, with the range.
        self.setRange(-1e12, 1e12)
        self.setKeyboardTracking(False)
        self.setAccelerated(True)
        if unit:
            self.setSuffix(f" {unit}")
        self.setButtonSymbols(QtWidgets.QAbstractSpinBox.ButtonSymbols.UpDownArrows)
        self.setFixedWidth(136)
        self.unit = unit
        #: Whether the parameter takes whole numbers only (said in a refusal's examples).
        self.whole = False
        #: What the last commit's text held: a number, a refusal, or None (the text was the value shown).
        self._typed: float | TypedTextError | None = None
        self.setFocusPolicy(QtCore.Qt.FocusPolicy.StrongFocus)  # the wheel does not take the focus

    def wheelEvent(self, event: QtGui.QWheelEvent) -> None:
        if not wheel_is_for_the_panel(self, event):
            super().wheelEvent(event)

    def validate(self, text: str, pos: int) -> tuple[QtGui.QValidator.State, str, int]:
        # Every keystroke is let in: the text is judged whole on commit, and a refusal is said, not swallowed.
        return QtGui.QValidator.State.Acceptable, text, pos

    def valueFromText(self, text: str) -> float:
        if text.strip() == f"{self.prefix()}{self.textFromValue(self.value())}{self.suffix()}".strip():
            self._typed = None  # Enter or a focus change on an unedited box: nothing asked
        else:
            # Qt puts the prefix and suffix back after every keystroke: what the user typed is between them.
            body = text.strip()
            prefix, suffix = self.prefix().strip(), self.suffix().strip()
            body = body[len(prefix):] if prefix and body.startswith(prefix) else body
            body = body[: -len(suffix)] if suffix and body.endswith(suffix) else body
            try:
                self._typed = read_typed(body, self.unit, self.whole)
            except TypedTextError as exc:
                self._typed = exc
        return self.value()  # the box shows what the model holds; the commit decides

    def keyPressEvent(self, event: QtGui.QKeyEvent) -> None:
        """Enter commits and hands the keys back to the window; Escape puts back the value held and hands them
        back too. The box then shows the value held: the new one, or on a refusal (said in red, with its tooltip)
        the old one. A first-use trial typed a value, pressed Enter, then e: "e deg" went into the box, and
        Escape did nothing."""
        key = event.key()
        if key == QtCore.Qt.Key.Key_Escape:
            self._typed = None
        else:
            super().keyPressEvent(event)
            if key not in (QtCore.Qt.Key.Key_Return, QtCore.Qt.Key.Key_Enter):
                return
        self.lineEdit().setText(f"{self.prefix()}{self.textFromValue(self.value())}{self.suffix()}")
        self.clearFocus()

    def take_typed(self) -> float | None:
        """The number typed since the last call (exact, not rounded to the decimals shown), or None.

        Raises
        ------
        TypedTextError
            The text was not a number of the box's unit.
        """
        typed, self._typed = self._typed, None
        if isinstance(typed, TypedTextError):
            raise typed
        return typed

    def stepBy(self, steps: int) -> None:
        fine = _fine(QtWidgets.QApplication.keyboardModifiers())
        direction = 1 if steps > 0 else -1
        # Qt multiplies a Ctrl+wheel step by ten; here Ctrl means the fine step.
        count = abs(steps) if not fine or abs(steps) < 10 else abs(steps) // 10
        delta = direction * count * (self.fine_step if fine else self.step)
        low, high = self.bounds
        self.setValue(min(max(self.value() + delta, low), high))
        self._typed = self.value()  # a step asks for its value as a typed one does
        self.editingFinished.emit()

    def textFromValue(self, value: float) -> str:
        return number_text(value)


class _ParamSlider(QtWidgets.QSlider):
    """A parameter's slider whose wheel steps the value by the parameter's step, as its box's does: in slider
    units, three notches moved CameraFOV 38.215 to 39.808 deg (a first-use trial)."""

    def __init__(self, step_value: Callable[[int], None]) -> None:
        super().__init__(QtCore.Qt.Orientation.Horizontal)
        self._step_value = step_value
        self._wheel_rest = 0
        self.setFocusPolicy(QtCore.Qt.FocusPolicy.StrongFocus)

    def wheelEvent(self, event: QtGui.QWheelEvent) -> None:
        if wheel_is_for_the_panel(self, event):
            return
        # A notch is 120; a touchpad sends less at a time: whole notches are stepped, the rest kept for the next.
        self._wheel_rest += event.angleDelta().y() or event.angleDelta().x()
        notches = int(self._wheel_rest / 120)
        self._wheel_rest -= notches * 120
        if notches:
            self._step_value(notches)
        event.accept()


class ParamRow(QtWidgets.QWidget):
    """One parameter: its title, a slider, a value box with the unit, the allowed range and a reset button.

    Parameters
    ----------
    name : str
        A key of :data:`~livox_viz.config.sensor.PARAM_RANGES`.
    value : float
        Its value now.
    preset_value : float or None
        The preset's value (what reset gives back); None: no reset.
    commit : callable
        ``commit(name, value) -> str | None``: ask for the value; why it was refused, or None when it was taken.
    say : callable, optional
        ``say(text)``: a message for the status bar (a typed text that is no number says so there too).
    """

    def __init__(self, name: str, value: float, preset_value: float | None,
                 commit: Callable[[str, float], str | None], parent: QtWidgets.QWidget | None = None,
                 say: Callable[[str], None] | None = None) -> None:
        super().__init__(parent)
        self.name = name
        self.setObjectName(f"param-{name}")
        self._commit = commit
        self._say = say
        self.preset_value = preset_value
        #: What the control said of the last value it refused ("" before any).
        self.refusal_text = ""
        doc = param_doc(name)
        spec = PARAM_RANGES[name]
        tip = describe(name)
        self.setToolTip(tip)
        self.title = QtWidgets.QLabel(doc.title)
        self.title.setToolTip(tip)
        self.title.setWordWrap(False)
        unit = f" {doc.unit}" if doc.unit else ""
        self.range_label = QtWidgets.QLabel(f"allowed {spec.describe()}{unit}".replace("an integer in ", ""))
        self.range_label.setObjectName("range")
        self.range_label.setToolTip(tip)
        self.slider = _ParamSlider(lambda notches: self.box.stepBy(notches))
        self.slider.setRange(0, SLIDER_STEPS)
        self.slider.setSingleStep(1)
        self.slider.setPageStep(SLIDER_STEPS // 20)
        self.slider.setToolTip(tip)
        self.box = ValueBox(value_bounds(name), doc.decimals, doc.step, doc.fine_step, doc.unit)
        self.box.whole = PARAM_RANGES[name].integer
        self.box.setToolTip(tip)
        self.reset_button = QtWidgets.QToolButton()
        self.reset_button.setText("↺")
        self.reset_button.setEnabled(preset_value is not None)
        self.reset_button.setToolTip(f"back to the preset's value, {preset_value:g}" if preset_value is not None
                                     else "no preset value")
        top = QtWidgets.QHBoxLayout()
        top.setContentsMargins(0, 0, 0, 0)
        top.addWidget(self.title, 1)
        top.addWidget(self.range_label)
        bottom = QtWidgets.QHBoxLayout()
        bottom.setContentsMargins(0, 0, 0, 0)
        bottom.addWidget(self.slider, 1)
        bottom.addWidget(self.box)
        bottom.addWidget(self.reset_button)
        layout = QtWidgets.QVBoxLayout(self)
        layout.setContentsMargins(2, 4, 2, 4)
        layout.setSpacing(2)
        layout.addLayout(top)
        layout.addLayout(bottom)
        self._drag_timer = QtCore.QTimer(self)
        self._drag_timer.setSingleShot(True)
        self._drag_timer.setInterval(LIVE_DRAG_MS)
        self._drag_timer.timeout.connect(self._commit_slider)
        self._refused_timer = QtCore.QTimer(self)
        self._refused_timer.setSingleShot(True)
        self._refused_timer.setInterval(1500)
        self._refused_timer.timeout.connect(lambda: self.box.setStyleSheet(""))
        self.show_value(value)
        self.slider.sliderPressed.connect(self._slider_pressed)
        self.slider.sliderMoved.connect(self._slider_moved)
        self.slider.sliderReleased.connect(self._commit_slider)
        self.slider.valueChanged.connect(self._slider_stepped)
        self.box.editingFinished.connect(self._commit_box)
        self.reset_button.clicked.connect(self.reset)
        keep_keys(self.slider, self.box)

    @property
    def value(self) -> float:
        """The value the row shows."""
        return float(self.box.value())

    def show_value(self, value: float) -> None:
        """Show ``value`` in the slider and the box without asking for it."""
        self._shown = float(value)
        with signals_blocked(self.slider, self.box):
            self.box.setValue(value)
            self.slider.setValue(round(slider_fraction(self.name, value) * SLIDER_STEPS))
        self.box.setStyleSheet("")

    def _slider_pressed(self) -> None:
        self._drag_origin = (self.slider.value(), slider_fraction(self.name, self._shown))

    def _slider_moved(self, position: int) -> None:
        """A drag: the value follows the handle, or, with Shift or Ctrl held, a tenth as fast (fine tuning: the
        handle then stays where the value is)."""
        origin = getattr(self, "_drag_origin", None)
        if origin is not None and _fine(QtWidgets.QApplication.keyboardModifiers()):
            fraction = origin[1] + (position - origin[0]) / SLIDER_STEPS / FINE_DRAG
            self._dragged = slider_value(self.name, fraction)
        else:
            self._dragged = slider_value(self.name, position / SLIDER_STEPS)
            self._drag_origin = (position, position / SLIDER_STEPS)
        with signals_blocked(self.box):
            self.box.setValue(self._dragged)
        if not self._drag_timer.isActive():
            self._drag_timer.start()

    def _slider_stepped(self, position: int) -> None:
        if not self.slider.isSliderDown():  # keys or a click on the groove: the value is final
            with signals_blocked(self.box):
                self.box.setValue(slider_value(self.name, position / SLIDER_STEPS))
            self._ask(self.box.value())

    def _commit_slider(self) -> None:
        self._drag_timer.stop()
        dragged = getattr(self, "_dragged", None)
        if dragged is None:
            dragged = slider_value(self.name, self.slider.value() / SLIDER_STEPS)
        if not self.slider.isSliderDown():
            self._dragged = None
            self._drag_origin = None
        self._ask(dragged)

    def _commit_box(self) -> None:
        try:
            value = self.box.take_typed()
        except TypedTextError as exc:
            spec = PARAM_RANGES[self.name]
            text = f"{exc}; allowed: {spec.describe()} {param_doc(self.name).unit}".strip()
            if self._say is not None:
                self._say(text)
            self._refuse(text)
            return
        spec = PARAM_RANGES[self.name]
        if value is not None and spec.integer and math.isfinite(value) and not float(value).is_integer():
            # Rounded, "150.5" showed 151 (Qt's rounding) while 150 ran (Python's, half to even).
            text = f"{value:g} refused: not a whole number; allowed: {spec.describe()} {param_doc(self.name).unit}"
            # Said in the status bar too, as every other refusal is (a trial saw only the box flash red, and an
            # older refusal stay in the status bar).
            if self._say is not None:
                self._say(text.strip())
            self._refuse(text.strip())
            return
        if value is not None and value != self._shown:
            self._ask(value)

    def reset(self) -> None:
        """Back to the preset's value."""
        if self.preset_value is not None:
            self._ask(self.preset_value)

    def _ask(self, value: float) -> None:
        if value == self._shown:
            return
        refusal = self._commit(self.name, value)
        if refusal is None:
            self.show_value(value)
            if QtWidgets.QToolTip.isVisible() and QtWidgets.QToolTip.text() == self.refusal_text:
                QtWidgets.QToolTip.hideText()  # the last refusal no longer holds
            return
        spec = PARAM_RANGES[self.name]
        unit = param_doc(self.name).unit
        # Inside the range, something else refused it (the point budget of DataWidth x DataHeight x DataCheckFreq,
        # say): its own words, not a range the value is in.
        self._refuse(f"{value:g} refused: {refusal}" if spec.contains(value)
                     else f"{value:g} refused; allowed: {spec.describe()} {unit}".strip())

    def _refuse(self, text: str) -> None:
        """Refused: the old value stays, and the control says why and what is allowed."""
        self.show_value(self._shown)
        # Only the box itself: a bare rule also dyed the refusal's tooltip (the box is its parent), dark on dark red.
        self.box.setStyleSheet("QAbstractSpinBox { background: #5c1f24; color: white; }")
        QtWidgets.QToolTip.showText(self.box.mapToGlobal(QtCore.QPoint(0, self.box.height())), text, self.box)
        self.refusal_text = text
        # A timer of the row's own: it dies with the row, should the panel be rebuilt before it fires.
        self._refused_timer.start()


class ParameterPanel(QtWidgets.QWidget):
    """Every control of the parameters in use: the pattern model's (or the return model's sheet), the frame
    structure, and playback (speed, integration window).

    Parameters
    ----------
    controller : LivoxVizApp
        Whose session the panel shows and asks.
    say : callable
        ``say(text)``: a refusal for the status bar (every message the panel says is one).
    """

    def __init__(self, controller, say: Callable[[str], None], parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self.controller = controller
        self.say = say
        self.setObjectName("parameter-panel")
        self.rows: dict[str, ParamRow] = {}
        self._layout = QtWidgets.QVBoxLayout(self)
        self._layout.setContentsMargins(6, 6, 6, 6)
        self._content: QtWidgets.QWidget | None = None
        self._layout_key: tuple | None = None
        self.rebuild()

    # Building --------------------------------------------------------------------------------
    def layout_key(self) -> tuple:
        """What decides the panel's rows: the pattern model, the page, the return model, the preset."""
        session = self.controller.session
        return (session.config.pattern_model, self.controller.page, session.config.returns_model,
                session.preset_name, session.config.risley is not None, session.config.track is not None)

    def follow(self) -> None:
        """Follow the session: rebuild when the rows change, else only show the values it holds."""
        if self.layout_key() != self._layout_key:
            self.rebuild()
        else:
            self.sync()

    def rebuild(self) -> None:
        """Make every control again from the session's state (the old ones deleted first)."""
        if self._content is not None:
            self._layout.removeWidget(self._content)
            self._content.setParent(None)
            self._content.deleteLater()
        self.rows = {}
        self._layout_key = self.layout_key()
        session = self.controller.session
        config = session.config
        content = QtWidgets.QWidget(self)
        content.setObjectName("panel-content")
        column = QtWidgets.QVBoxLayout(content)
        column.setContentsMargins(0, 0, 0, 0)
        column.setSpacing(8)
        page = self.controller.page
        if page == "returns":
            # The page's figures are the datasheet model's whichever model runs ("Return model: ideal sheet" over
            # them read as if the ideal model had a sheet of its own).
            title = ("Return model: datasheet" if config.returns_model == "datasheet"
                     else f"Return model: datasheet's figures (running: {config.returns_model})")
            names = RETURN_PARAMS
        else:
            title = _MODEL_TITLES.get(config.pattern_model, "Pattern")
            names = PATTERN_PARAMS[config.pattern_model]
        column.addWidget(self._group(title, names, config))
        if page == "returns" and config.returns_model != "datasheet":
            note = QtWidgets.QLabel("These figures act with the datasheet return model (Returns menu, or d).")
            note.setWordWrap(True)
            column.insertWidget(0, note)
        column.addWidget(self._group(self._frame_title(config), frame_params(config), config))
        column.addWidget(self._playback_group())
        column.addStretch(1)
        self._layout.addWidget(content)
        self._content = content

    def _frame_title(self, config: SensorConfig) -> str:
        return (f"Frame: {config.data_width} x {config.data_height} x {config.data_check_freq} Hz = "
                f"{config.point_rate:,} pts/s")

    def _group(self, title: str, names: tuple[str, ...], config: SensorConfig) -> QtWidgets.QGroupBox:
        box = QtWidgets.QGroupBox(title)
        box.setObjectName(f"group-{title.split(':')[0].lower()}")
        layout = QtWidgets.QVBoxLayout(box)
        layout.setSpacing(2)
        preset = self.controller.session.preset_config
        for name in names:
            try:
                value = config.param_value(name)
            except LivoxVizError:
                continue  # a parameter this configuration does not have
            try:
                preset_value = preset.param_value(name) if preset is not None else None
            except LivoxVizError:
                preset_value = None
            row = ParamRow(name, value, preset_value, self._commit, box, say=self.say)
            layout.addWidget(row)
            self.rows[name] = row
        return box

    def _playback_group(self) -> QtWidgets.QGroupBox:
        session = self.controller.session
        box = QtWidgets.QGroupBox("Playback")
        box.setObjectName("group-playback")
        form = QtWidgets.QFormLayout(box)
        self.speed_box = ValueBox(SPEED_RANGE, 3, 0.5, 0.05, "x real time")
        self.speed_box.setToolTip(f"scan seconds per second of wall time; allowed: {SPEED_RANGE[0]:g} to "
                                  f"{SPEED_RANGE[1]:g} (Up / Down double and halve it)")
        self.speed_box.setValue(session.playback.speed)
        self.speed_box.editingFinished.connect(self._commit_speed)
        form.addRow("speed", self.speed_box)
        self.window_choice = NoWheelUnlessFocused()
        for window in WINDOWS:
            self.window_choice.addItem("unlimited (1 M points)" if window is None else f"{window:g} s", window)
        self.window_choice.addItem("typed", "typed")
        self.window_choice.setToolTip("the integration window: the points of the last so many seconds (i cycles)")
        self.window_box = ValueBox(WINDOW_RANGE, 3, 0.1, 0.01, "s")
        self.window_box.setToolTip(f"any integration window from {WINDOW_RANGE[0]:g} to {WINDOW_RANGE[1]:g} s")
        # Unlimited, the greyed box said "0 s": it says "unlimited" (shown for its lowest value, kept for that).
        self.window_box.setSpecialValueText("unlimited")
        row = QtWidgets.QHBoxLayout()
        row.addWidget(self.window_choice, 1)
        row.addWidget(self.window_box)
        form.addRow("window", row)
        self._show_window()
        keep_keys(self.speed_box, self.window_choice, self.window_box)
        self.window_choice.activated.connect(self._window_chosen)
        self.window_box.editingFinished.connect(self._window_typed)
        return box

    # Following the session ------------------------------------------------------------------------
    def sync(self) -> None:
        """Show the session's values (no rebuild)."""
        config = self.controller.session.config
        for name, row in self.rows.items():
            try:
                value = config.param_value(name)
            except LivoxVizError:
                continue
            if value != row.value:
                row.show_value(value)
        frame_group = self.findChild(QtWidgets.QGroupBox, "group-frame")
        if frame_group is not None:
            frame_group.setTitle(self._frame_title(config))
        self.show_playback()

    def show_playback(self) -> None:
        """Show the session's playback speed and integration window (Up, Down, i and the menus change them)."""
        with signals_blocked(self.speed_box):
            self.speed_box.setValue(self.controller.session.playback.speed)
        self._show_window()

    def _show_window(self) -> None:
        window = self.controller.session.window
        index = self.controller.session.window_index
        with signals_blocked(self.window_choice, self.window_box):
            self.window_choice.setCurrentIndex(index if index is not None else len(WINDOWS))
            self.window_box.setEnabled(window is not None)
            self.window_box.setValue(self.window_box.minimum() if window is None else window)

    # Asking ----------------------------------------------------------------------------------------
    def _commit(self, name: str, value: float) -> str | None:
        if self.controller.on_param(name, value):
            return None
        refusal = self.controller.session.message or f"{name} = {value:g} refused"
        self.say(refusal)
        return refusal

    def _typed(self, box: ValueBox, allowed: str) -> float | None:
        """The number typed in a playback box, or None (nothing typed, or a refusal said in the status bar)."""
        try:
            return box.take_typed()
        except TypedTextError as exc:
            self.say(f"{exc}; allowed: {allowed}")
            return None

    def _commit_speed(self) -> None:
        allowed = f"{SPEED_RANGE[0]:g} to {SPEED_RANGE[1]:g} x"
        value = self._typed(self.speed_box, allowed)
        if value is None or value == self.controller.session.playback.speed:
            return
        if not (math.isfinite(value) and SPEED_RANGE[0] <= value <= SPEED_RANGE[1]):
            self.say(f"speed {value:g} refused; allowed: {allowed}")
            with signals_blocked(self.speed_box):
                self.speed_box.setValue(self.controller.session.playback.speed)
            return
        self.controller.on_speed(value)
        self.show_playback()  # the box kept showing 10 x after 0.5 was taken (a first-use trial)

    def _window_chosen(self, index: int) -> None:
        chosen = self.window_choice.itemData(index)
        if chosen == "typed":
            if self.window_box.value() == self.window_box.minimum():  # from unlimited: a number to start from
                with signals_blocked(self.window_box):
                    self.window_box.setValue(1.0)
            self.window_box.setEnabled(True)
            self.window_box.setFocus()
            return
        self._set_window(chosen)

    def _window_typed(self) -> None:
        value = self._typed(self.window_box, f"{WINDOW_RANGE[0]:g} to {WINDOW_RANGE[1]:g} s")
        if value is not None:
            self._set_window(value)

    def _set_window(self, seconds: float | None) -> None:
        if seconds == self.controller.session.window:
            return
        try:
            self.controller.set_window_seconds(seconds)
        except LivoxVizError as exc:
            self.say(str(exc))
        self._show_window()
