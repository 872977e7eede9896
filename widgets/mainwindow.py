"""The livox-viz window: a Qt main window around the VTK views, with native controls.

The pattern view, the scene view and the charts are pyvistaqt interactors
side by side in a splitter (each its own render window: the charts are drawn
only when they change); the parameter panel is a dock built from the model's
parameter table (:mod:`~livox_viz.widgets.panel`); menus hold every action,
and every key of the key table (:mod:`~livox_viz.widgets.keys`) is a shortcut;
the status bar shows the scan time, the points in the window and fired, the
frame rate, the return model, what is being prepared in the background, and
messages.

Nothing slow runs on the UI thread: the compiled loops load in the background
(:class:`~livox_viz.widgets.warmup.LoopWarmer`; a configuration that needs
loops not loaded yet is applied when they are, the window playing the old one
meanwhile), and a fit, a scene or mesh, a reference table and an export run
on worker threads. A broken file opened from the menu leaves the window as it
was, with a message naming what is wrong.
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time
from collections.abc import Callable, Iterable
from concurrent.futures import Future
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault("QT_API", "pyside6")

from pyvistaqt import QtInteractor
from qtpy import QtCore, QtGui, QtWidgets

from livox_viz import LivoxVizError, list_presets, load_config
from livox_viz.casting.warm import STAGES, stages_for
from livox_viz.config.sensor import save_config

from . import files
from .app import VIEW_NAMES, LivoxVizApp, quiet_vtk
from .cameras import PROJECTIONS
from .collector import MainThreadCollector, destroy_widget_tree, give_back_free_memory, release_gl_wrappers
from .colour_range import RANGE_UNITS
from .filter_dialog import FilterDialog
from .guide import GUIDE_SIZE, UserGuide, guide_dir
from .history import describe_change
from .keys import KEYS, help_html
from .messages import LOG_SIZE, MessageLog, MessagesDialog
from .nonerefs import NoneReserve, binding_drops_none
from .overlay import WINDOWS, PresetSource, TableSource, window_label
from .panel import ParameterPanel, signals_blocked
from .picks_panel import PicksPanel
from .range_dialog import AUTOMATIC, ColourRangeDialog
from .session import DRAWINGS, SCENE_COLOURS, Session, pattern_colours, step_units
from .viewpoints import NAME_CHARS, delete_viewpoint, read_viewpoints, save_viewpoint
from .views import BACKGROUNDS, CAMERA_PRESETS, COLOUR_MAPS
from .warmup import LoopWarmer

TIMER_MS = 33
#: The events that may change what the window shows without changing the scan's state (see MainWindow._resting).
_INPUT_EVENTS = frozenset({QtCore.QEvent.Type.KeyPress, QtCore.QEvent.Type.KeyRelease,
                           QtCore.QEvent.Type.MouseButtonPress, QtCore.QEvent.Type.MouseButtonRelease,
                           QtCore.QEvent.Type.MouseButtonDblClick, QtCore.QEvent.Type.Wheel,
                           QtCore.QEvent.Type.Shortcut, QtCore.QEvent.Type.Resize, QtCore.QEvent.Type.Show})
#: Qt's names of the key table's VTK key symbols.
QT_KEYS = {"space": "Space", "Right": "Right", "Up": "Up", "Down": "Down"}
#: The key table's key of each method it binds (a menu entry calling one shows its key).
KEY_OF_METHOD = {method: key for row in KEYS for key, method in row.bindings}
#: Formats the window's cloud can be exported to (the writers of ``livox-viz scan``).
#: The Livox formats take only their own heads (a preset of another is refused in one line, before any work).
EXPORT_FORMATS = (("PLY", ".ply"), ("PCD", ".pcd"), ("LAS 1.4", ".las"), ("NumPy NPZ", ".npz"), ("CSV", ".csv"),
                  ("Livox LVX2: Mid-360, HAP", ".lvx2"),
                  ("Livox LVX 1.1: Mid-40, Mid-70, Horizon, Avia, Tele-15", ".lvx"))
#: Points a refilled integration window casts per tick: about 40 ms of the ideal model's work on one core.
FILL_PER_TICK = 40_000
#: Seconds closing the window waits for a job it gave up to remove what it was writing (one frame's work).
CANCEL_WAIT_S = 10.0
#: Pixels of the status bar the message keeps beside what is being prepared (less when it needs less).
STATUS_MESSAGE_SHARE = 300
#: Pixels a click may move between press and release and still be a click (not a drag of the camera).
CLICK_SLOP = 4
#: Pixels the Picks panel takes under the views when it opens (at most a quarter of the window's height).
PICKS_PANEL_HEIGHT = 190


def key_sequence(key: str) -> QtGui.QKeySequence:
    """Qt's key sequence of a key of the key table."""
    return QtGui.QKeySequence(QT_KEYS.get(key, key.upper() if len(key) == 1 else key))


def application() -> QtWidgets.QApplication:
    """The Qt application of this process (made once)."""
    app = QtWidgets.QApplication.instance()
    if app is None:
        QtWidgets.QApplication.setApplicationName("livox-viz")
        app = QtWidgets.QApplication(["livox-viz"])
    return app


class ElidedLabel(QtWidgets.QLabel):
    """A one-line label for the status bar: when its text is wider than the room it gets, it shows what fits and
    an ellipsis, and the whole text is its tooltip (a long message was cut at the bar's edge without a sign),
    followed by ``more`` when given.

    :meth:`text` is the whole text; the label asks for its width, at most ``widest`` pixels, but takes less (down
    to an ellipsis). A click (a press and release in one place that selects nothing) emits :attr:`clicked`.
    """

    clicked = QtCore.Signal()

    def __init__(self, widest: int = 1 << 20, parent: QtWidgets.QWidget | None = None, more: str = "") -> None:
        super().__init__(parent)
        self._whole = ""
        self._widest = widest
        self._more = more
        self._pressed_at: QtCore.QPointF | None = None

    def mousePressEvent(self, event: QtGui.QMouseEvent) -> None:
        self._pressed_at = event.position() if event.button() == QtCore.Qt.MouseButton.LeftButton else None
        super().mousePressEvent(event)

    def mouseReleaseEvent(self, event: QtGui.QMouseEvent) -> None:
        super().mouseReleaseEvent(event)
        pressed, self._pressed_at = self._pressed_at, None
        if pressed is not None and event.button() == QtCore.Qt.MouseButton.LeftButton \
                and (event.position() - pressed).manhattanLength() <= CLICK_SLOP and not self.hasSelectedText():
            self.clicked.emit()

    def setText(self, text: str) -> None:
        if text == self._whole:
            return
        self._whole = text
        self.updateGeometry()
        self._elide()

    def text(self) -> str:
        return self._whole

    def set_widest(self, widest: int) -> None:
        """Ask for at most ``widest`` pixels from now on."""
        if widest != self._widest:
            self._widest = widest
            self.updateGeometry()

    def shown_text(self) -> str:
        """What the label shows now (the text, or its start and an ellipsis)."""
        return super().text()

    def sizeHint(self) -> QtCore.QSize:
        margins = self.contentsMargins()
        # Rounded up: the whole pixels of horizontalAdvance round a text's width down as often as up, and the
        # elision (which measures in fractions) then cut "loading dense_terrain" to "loading dense_terr..." with
        # the bar's room to spare.
        text_width = math.ceil(QtGui.QFontMetricsF(self.font()).horizontalAdvance(self._whole))
        width = text_width + margins.left() + margins.right() + 2
        return QtCore.QSize(min(width, self._widest), super().sizeHint().height())

    def minimumSizeHint(self) -> QtCore.QSize:
        return QtCore.QSize(min(self.sizeHint().width(), self.fontMetrics().horizontalAdvance("...") * 3),
                            super().minimumSizeHint().height())

    def resizeEvent(self, event: QtGui.QResizeEvent) -> None:
        super().resizeEvent(event)
        self._elide()

    def _elide(self) -> None:
        room = max(self.contentsRect().width() - 2, 0)
        shown = self.fontMetrics().elidedText(self._whole, QtCore.Qt.TextElideMode.ElideRight, room)
        if shown != super().text():
            super().setText(shown)
        tip = (self._whole + (f"\n\n{self._more}" if self._more else "")) if shown != self._whole else ""
        if tip != self.toolTip():
            self.setToolTip(tip)


@dataclass
class _Job:
    """A background job the status bar shows: what it is, its future, and what to do with its result."""

    what: str
    future: Future
    done: Callable[[Any], None]
    started: float
    #: The share done, 0 to 1, when the job can tell.
    fraction: Callable[[], float] | None = None
    #: Gives the job up (when the window closes), when it can be.
    cancel: Callable[[], None] | None = None

    def describe(self) -> str:
        return self.what if self.fraction is None else f"{self.what} {100 * self.fraction():.0f} %"


def short_description(text: str, most: int = 60) -> str:
    """``text`` up to its first "; " or ". " (its first clause), cut at a word and ended with an ellipsis past
    ``most`` characters."""
    for stop in ("; ", ". "):
        text = text.split(stop, 1)[0]
    if len(text) <= most:
        return text
    return text[: text.rfind(" ", 0, most - 1)].rstrip(",:;") + "\u2026"


class _ScrubSlider(QtWidgets.QSlider):
    """A slider whose bar, clicked outside the handle, moves the handle's middle under the cursor and lets it be
    dragged on from there, as a media player's does (Qt's default: a page step, 1.8 s of a long scan, which a
    first-use trial took for a broken bar). A subclass, not a proxy style: a widget does not own its style, and
    one that died before the slider left it a dangling one.

    :attr:`held` is true while the handle is held (dragged, or jumping to a click): its moves are shown, not yet
    sought (the seek comes with ``sliderReleased``).
    """

    def __init__(self, orientation: QtCore.Qt.Orientation, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(orientation, parent)
        self._jumping = False

    @property
    def held(self) -> bool:
        return self._jumping or self.isSliderDown()

    def _rect(self, part: QtWidgets.QStyle.SubControl) -> QtCore.QRect:
        option = QtWidgets.QStyleOptionSlider()
        self.initStyleOption(option)
        return self.style().subControlRect(QtWidgets.QStyle.ComplexControl.CC_Slider, option, part, self)

    def handle_rect(self) -> QtCore.QRect:
        """The handle's rectangle, in the slider's pixels."""
        return self._rect(QtWidgets.QStyle.SubControl.SC_SliderHandle)

    def value_under(self, x: float) -> int:
        """The value that puts the handle's middle at ``x`` (the slider's pixels), as Qt maps a handle's place to a
        value: along the groove less the handle's length."""
        groove, handle = self._rect(QtWidgets.QStyle.SubControl.SC_SliderGroove), self.handle_rect()
        span = max(groove.width() - handle.width(), 1)
        place = round(x - handle.width() / 2) - groove.x()
        return QtWidgets.QStyle.sliderValueFromPosition(self.minimum(), self.maximum(), place, span,
                                                        self.invertedAppearance())

    def mousePressEvent(self, event: QtGui.QMouseEvent) -> None:
        point = event.position().toPoint()
        if event.button() == QtCore.Qt.MouseButton.LeftButton and self.isEnabled() \
                and not self.handle_rect().contains(point):
            self._jumping = True
            try:
                self.setValue(self.value_under(event.position().x()))
            finally:
                self._jumping = False
            # The handle is under the cursor now: Qt's own press grabs it, so a drag goes on from the click.
            super().mousePressEvent(event)
            if not self.isSliderDown():  # not grabbed after all: the jump was the whole move
                self.sliderReleased.emit()
            return
        super().mousePressEvent(event)


class MainWindow(QtWidgets.QMainWindow):
    """The window.

    Parameters
    ----------
    session : Session
    size : tuple of int
        The window's pixels.
    stop : callable, optional
        Checked every tick; true closes the window (a signal noted by the command line).
    screenshot_dir : Path
    warm : bool
        Load the compiled loops in the background (tests that need none pass False).
    warmer : LoopWarmer, optional
        The loader to use (the window starts it after its first frame, unless it was started already).
    """

    def __init__(self, session: Session, size: tuple[int, int] = (1600, 900), stop: Callable[[], bool] | None = None,
                 screenshot_dir: Path = files.SCREENSHOT_DIR, warm: bool = True,
                 warmer: LoopWarmer | None = None) -> None:
        application()
        super().__init__()
        # A binding that takes a reference off None in each call (PySide6 6.12.0 on Python 3.11) ended the window
        # within minutes: None's lost references are given back each tick (see widgets/nonerefs.py).
        self.none_reserve = NoneReserve() if binding_drops_none() else None
        if self.none_reserve is not None:
            print("livox-viz: this PySide6 drops references to None on Python 3.11 (a bug of PySide6 6.12.0); the "
                  "window makes up for it, installing PySide6-Essentials<6.12 avoids it", file=sys.stderr)
        # Cycles are collected in this thread, at each tick: see widgets/collector.py (a frozen window). Started
        # last, once the window is made: a set-up that failed would have left collection off in the process.
        self.collector = MainThreadCollector()
        quiet_vtk()
        self.setObjectName("livox-viz")
        self.resize(*fit_to_screen(size, self._available_area()))
        self._stop = stop
        self._jobs: list[_Job] = []
        #: Changes waiting for their compiled loops, by kind: (stages, action, what).
        self._pending: dict[str, tuple[set[str], Callable[[], None], str]] = {}
        #: The refusal or failure the status bar shows in red while it is the message (a later message is not red).
        self._error_text: str | None = None
        #: Every message the status bar said, whole (View > Messages).
        self.messages = MessageLog()
        self._press: tuple[str, int, int] | None = None
        #: How many picks the Picks panel showed last (it opens when a list starts).
        self._picks_shown = 0
        self._closing = False
        self._sized = False
        self._pattern_size: tuple[int, int] | None = None

        # The views: one interactor each, side by side.
        self.splitter = QtWidgets.QSplitter(QtCore.Qt.Orientation.Horizontal, self)
        self.splitter.setObjectName("views")
        self.interactors: dict[str, QtInteractor] = {}
        for name in VIEW_NAMES:
            interactor = QtInteractor(self.splitter, auto_update=False, multi_samples=0, line_smoothing=True)
            interactor.setObjectName(f"{name}-view")
            interactor.setMinimumSize(240, 240)
            self.splitter.addWidget(interactor)
            self.interactors[name] = interactor
        self.splitter.setSizes([5, 4, 3])
        self.splitter.setChildrenCollapsible(False)
        self.setCentralWidget(self.splitter)
        # A new window or a seek is cast again a share each tick (a million points at once took seconds).
        session.fill_per_tick = FILL_PER_TICK
        self.controller = LivoxVizApp(session, plotters=self.interactors, screenshot_dir=screenshot_dir)
        self.controller.defer = self._defer
        self.controller.on_panel_change = self._panel_follow
        for name, interactor in self.interactors.items():
            self._quiet_vtk_keys(interactor)
            if name in ("pattern", "scene"):
                self._watch_clicks(name, interactor)

        # The parameter panel.
        self.panel = ParameterPanel(self.controller, lambda text: self.say(text, error=True))  # its refusals
        scroll = QtWidgets.QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setWidget(self.panel)
        # Sideways too when the dock is narrower than the rows (a small window): with no bar, an 1100 px window
        # cut the track's range labels and reset buttons off with no way to reach them (a first-use trial).
        scroll.setHorizontalScrollBarPolicy(QtCore.Qt.ScrollBarPolicy.ScrollBarAsNeeded)
        self.dock = QtWidgets.QDockWidget("Parameters", self)
        self.dock.setObjectName("parameters")
        self.dock.setWidget(scroll)
        self.dock.setFeatures(QtWidgets.QDockWidget.DockWidgetFeature.DockWidgetMovable
                              | QtWidgets.QDockWidget.DockWidgetFeature.DockWidgetFloatable
                              | QtWidgets.QDockWidget.DockWidgetFeature.DockWidgetClosable)
        self.dock.setMinimumWidth(330)
        self.addDockWidget(QtCore.Qt.DockWidgetArea.LeftDockWidgetArea, self.dock)
        # The picks' list, under the views (the parameter panel keeps the window's height: the left dock holds the
        # bottom-left corner); hidden until the first pick.
        self.setCorner(QtCore.Qt.Corner.BottomLeftCorner, QtCore.Qt.DockWidgetArea.LeftDockWidgetArea)
        self.picks_panel = PicksPanel(self.controller, self.run, self)
        self.addDockWidget(QtCore.Qt.DockWidgetArea.BottomDockWidgetArea, self.picks_panel)
        self.picks_panel.hide()
        self.controller.on_picks_change = self._picks_follow

        self._make_status_bar()
        self._make_scrubber()
        #: The keys of the key table a menu entry's action holds (:meth:`_action`).
        self._menu_keys: set[str] = set()
        self._history_shown = -1
        self._live_shown = ""
        self._make_menus()
        # The choices' menus show the current one from the start, and whatever changed it since (the panel, a
        # preset's own return model, a change that waited for its loops): none was checked before the first key.
        self._sync_menus()
        for top in self.menuBar().actions():
            top.menu().aboutToShow.connect(self._sync_menus)
        self._make_shortcuts()
        self.help_dialog: QtWidgets.QDialog | None = None
        self.guide: UserGuide | None = None
        self.messages_dialog: MessagesDialog | None = None

        # The compiled loops: what the first frame needs now, the rest in the background.
        moving = session.trajectory is not None
        self.warmer: LoopWarmer | None = warmer
        if warm and warmer is None:
            self.warmer = LoopWarmer(stages_for(session.config, moving), STAGES)
        # The pattern plays as soon as its own loops are there (none for the rosette); the scene's cloud joins when
        # the caster's are (the window then casts its integration window again).
        self._playing_allowed = self.warmer is None
        if self.warmer is not None:
            session.casting = False
        self._first_frame: float | None = None
        self.opened = time.perf_counter()

        #: The scan a trim of the heap followed last, when the next one is due, and how many were done.
        self._trimmed_scan = -1
        self._trim_due: float | None = None
        self.memory_trims = 0
        #: Input events the application took (keys, clicks, the wheel), and what the last tick at rest saw.
        self._inputs = 0
        self._rest_signature: tuple | None = None
        QtWidgets.QApplication.instance().installEventFilter(self)
        self.timer = QtCore.QTimer(self)
        self.timer.setInterval(TIMER_MS)
        self.timer.timeout.connect(self.tick)
        self.timer.start()
        self._update_title()
        self._update_status()
        self.collector.start()

    # Set-up ---------------------------------------------------------------------------------------
    def _quiet_vtk_keys(self, interactor: QtInteractor) -> None:
        """VTK's and pyvista's own keys (q closes the view, e exits, 3 turns on stereo, w wireframes...) do nothing
        in our views: every key is one of ours, through Qt."""
        iren = interactor.iren
        if iren is None:
            return
        iren.interactor.RemoveObservers("KeyPressEvent")
        iren.interactor.RemoveObservers("CharEvent")

        def swallow(vtk_interactor, _event: str) -> None:
            vtk_interactor.SetKeyCode("\0")
            vtk_interactor.SetKeySym("")

        iren.interactor.AddObserver("CharEvent", swallow, 100.0)
        iren.interactor.AddObserver("KeyPressEvent", swallow, 100.0)

    def _watch_clicks(self, name: str, interactor: QtInteractor) -> None:
        """A click (press and release in one place) on a view picks; a drag still turns the camera."""
        iren = interactor.iren
        if iren is None:
            return

        def pressed(*_: object) -> None:
            x, y = iren.interactor.GetEventPosition()
            self._press = (name, x, y)

        def released(*_: object) -> None:
            x, y = iren.interactor.GetEventPosition()
            press, self._press = self._press, None
            if press is None or press[0] != name or abs(press[1] - x) > CLICK_SLOP or abs(press[2] - y) > CLICK_SLOP:
                return
            self.pick(name, x, y)

        # pyvista puts a release's observer on the interactor's style: the interactor swallows the release.
        iren.add_observer("LeftButtonPressEvent", pressed)
        iren.add_observer("LeftButtonReleaseEvent", released)

    def _make_status_bar(self) -> None:
        bar = self.statusBar()
        bar.setObjectName("status")
        self.status_time = QtWidgets.QLabel()
        self.status_points = QtWidgets.QLabel()
        self.status_fps = QtWidgets.QLabel()
        self.status_returns = QtWidgets.QLabel()
        self.busy = QtWidgets.QProgressBar()
        self.busy.setRange(0, 0)  # a busy indicator, not a percentage
        self.busy.setMaximumWidth(90)
        self.busy.setMaximumHeight(14)
        self.busy.setVisible(False)
        # Both give way to the permanent figures at the right, with an ellipsis and the whole text as tooltip; what
        # is being prepared takes the room it needs, but leaves the message (feedback to what was just done) its
        # share (_share_status_room): capped at 320 px, its note on the first compile was cut with 600 px to spare.
        self.status_busy = ElidedLabel()
        # A click on the message shows every message whole (View > Messages): the tooltip of a message cut short
        # could not be copied, nor read again once the next one came.
        self.status_message = ElidedLabel(more="Click: every message whole, to read and copy (View > Messages)")
        self.status_message.setObjectName("message")
        self.status_message.setTextInteractionFlags(QtCore.Qt.TextInteractionFlag.TextSelectableByMouse)
        self.status_message.clicked.connect(self.show_messages)
        for widget in (self.status_time, self.status_points, self.status_fps, self.status_returns):
            bar.addPermanentWidget(widget)
        bar.addWidget(self.busy)
        bar.addWidget(self.status_busy)
        bar.addWidget(self.status_message, 1)

    def _make_scrubber(self) -> None:
        """The time scrubber: a toolbar slider over the scan time played so far, active when paused."""
        bar = QtWidgets.QToolBar("Time", self)
        bar.setObjectName("time-bar")
        bar.setMovable(False)
        self.scrub_label = QtWidgets.QLabel(" scan time ")
        self.scrubber = _ScrubSlider(QtCore.Qt.Orientation.Horizontal)
        self.scrubber.setObjectName("scrubber")
        self.scrubber.setRange(0, 1000)
        self.scrubber.setToolTip("pause (space), then click or drag to look back at any scan time played so far")
        self.scrubber.sliderReleased.connect(self._scrubbed)
        self.scrubber.valueChanged.connect(self._scrub_moved)
        bar.addWidget(self.scrub_label)
        bar.addWidget(self.scrubber)
        self.addToolBar(QtCore.Qt.ToolBarArea.BottomToolBarArea, bar)

    @property
    def _played(self) -> float:
        """The scan time the scrubber spans: as far as the scan played since it last restarted, seconds."""
        return self.controller.session.played

    def _available_area(self) -> tuple[int, int] | None:
        """The size of the screen's area a window may take (without task bars), pixels; None without a screen."""
        screen = self.screen() or QtGui.QGuiApplication.primaryScreen()
        if screen is None:
            return None
        area = screen.availableGeometry()
        return area.width(), area.height()

    def _action(self, menu: QtWidgets.QMenu, text: str, slot: Callable[[], Any], shortcut: str | None = None,
                checkable: bool = False, group: QtGui.QActionGroup | None = None, data: Any = None) -> QtGui.QAction:
        action = QtGui.QAction(text, self)
        if shortcut:
            action.setShortcut(QtGui.QKeySequence(shortcut))
            action.setShortcutContext(QtCore.Qt.ShortcutContext.WindowShortcut)
        elif getattr(slot, "__name__", None) in KEY_OF_METHOD:
            # The menu shows the key at the right of the entry and the action is that key's only shortcut, window
            # wide (_make_shortcuts leaves it out): two shortcuts on one key are ambiguous and Qt runs neither. Tied
            # to its menu (WidgetShortcut) it still matched once the menu bar had the focus (after Escape closed a
            # menu): every such key then did nothing. A focused control keeps its own keys (KeepKeys).
            key = KEY_OF_METHOD[slot.__name__]
            action.setShortcut(key_sequence(key))
            action.setShortcutContext(QtCore.Qt.ShortcutContext.WindowShortcut)
            self._menu_keys.add(key)
        action.setCheckable(checkable)
        if group is not None:
            group.addAction(action)
        if data is not None:
            action.setData(data)
        action.triggered.connect(lambda _checked=False: self.run(slot))
        menu.addAction(action)
        return action

    def _choices(self, menu: QtWidgets.QMenu, title: str, choices: Iterable[Any], choose: Callable[[Any], Any],
                 label: Callable[[Any], str] = str,
                 following: tuple[str, Callable[[], Any]] | None = None) -> dict[Any, QtGui.QAction]:
        """A submenu ``title`` of ``menu`` holding one checkable action per choice, one checked at a time; its
        actions by choice. Choosing calls ``choose(choice)``. ``following``: (text, slot) of an entry after them
        that steps to the next choice (it shows the slot's key)."""
        submenu = menu.addMenu(title)
        group = QtGui.QActionGroup(self)
        actions = {choice: self._action(submenu, label(choice), lambda x=choice: choose(x), checkable=True,
                                        group=group)
                   for choice in choices}
        if following is not None:
            submenu.addSeparator()
            self._action(submenu, *following)
        return actions

    def _make_menus(self) -> None:
        c = self.controller
        bar = self.menuBar()
        file = bar.addMenu("&File")
        self._action(file, "Open sensor config or preset file...", self.open_config, "Ctrl+O")
        presets = file.addMenu("Open preset")
        presets.aboutToShow.connect(lambda: self._fill_presets(presets))
        self._action(file, "Open scene or mesh file...", self.open_scene)
        scenes = file.addMenu("Open built-in scene")
        scenes.aboutToShow.connect(lambda: self._fill_scenes(scenes))
        self._action(file, "Next built-in scene", self.cycle_scene)
        self._action(file, "Open reference table, recording or preset...", self.open_reference)
        tables = file.addMenu("Open shipped reference table")
        tables.aboutToShow.connect(lambda: self._fill_tables(tables))
        self._action(file, "Open cloud (PLY, PCD, LAS, NPZ, CSV, LVX2, LVX, bag) beside the scan...", self.open_cloud)
        self._action(file, "Close cloud", self.close_cloud)
        file.addSeparator()
        self._action(file, "Save as user preset", c.save_preset)
        self._action(file, "Save configuration as...", self.save_config_as, "Ctrl+S")
        export = file.addMenu("Export the window's cloud")
        for label, suffix in EXPORT_FORMATS:
            self._action(export, f"{label} ({suffix})...", lambda s=suffix: self.export_cloud(s))
        self._action(file, "Export ROS 2 bag...", self.export_bag)
        self._action(file, "Screenshot (views and sidecar)", c.take_screenshot)
        file.addSeparator()
        # q, the key table's, shown at the entry; Ctrl+Q as well, as every program has it.
        quit_action = self._action(file, "Quit", self.quit)
        quit_action.setShortcuts([*quit_action.shortcuts(), QtGui.QKeySequence("Ctrl+Q")])

        # Undo and redo of the configuration, named as editors name them ("Undo DataWidth 250 -> 116").
        edit = bar.addMenu("&Edit")
        self.undo_action = self._action(edit, "Undo", c.undo)
        self.redo_action = self._action(edit, "Redo", c.redo)
        self.redo_action.setShortcuts([*self.redo_action.shortcuts(), QtGui.QKeySequence("Ctrl+Y")])
        edit.aboutToShow.connect(self._sync_history)

        view = bar.addMenu("&View")
        # c, k, g, u and i step through a submenu's choices: each submenu ends in a "Next" entry showing its key, as
        # d's and v's entries do (a first-use trial found these keys in no menu).
        self.pattern_colour_menu = view.addMenu("Colour the pattern by")
        self._next_pattern_colour = self._action(self.pattern_colour_menu, "Next pattern colouring",
                                                 c.cycle_pattern_colour)
        self.pattern_colour_menu.aboutToShow.connect(self._fill_pattern_colours)
        self._fill_pattern_colours()
        self.scene_colour_actions = self._choices(view, "Colour the cloud by", SCENE_COLOURS, c.set_scene_colour,
                                                  following=("Next cloud colouring", c.cycle_scene_colour))
        self.colour_map_actions = self._choices(view, "Colour map (time, range, height)", COLOUR_MAPS,
                                                self.set_colour_map)
        self.point_size_actions = self._choices(view, "Point size", (1, 2, 3, 4, 6, 8), self.set_point_size,
                                                label="{} px".format)
        self.background_actions = self._choices(view, "Background", BACKGROUNDS, self.set_background)
        self.drawing_actions = self._choices(view, "Pattern drawing", DRAWINGS, self.set_drawing,
                                             following=("Next drawing", c.cycle_drawing))
        view.addSeparator()
        self.grid_action = self._action(view, "Ground grid in the scene", self.toggle_grid, checkable=True)
        self.axes_action = self._action(view, "World axes in the scene", self.toggle_axes, checkable=True)
        cameras = view.addMenu("Scene camera")
        for preset in CAMERA_PRESETS:
            self._action(cameras, f"{preset}", lambda p=preset: c.set_scene_camera(p))
        self.follow_action = self._action(cameras, "follow the vehicle", lambda: c.set_scene_camera("follow"),
                                          checkable=True)
        self._make_scene_view_menus(view)
        self._action(view, "Reset cameras (fit everything drawn)", c.reset_cameras)
        self._action(view, "Turn the scene camera about the last pick", c.turn_about_last_pick)
        self._action(view, "Colour range of the cloud (min, max or automatic)...", self.type_colour_range)
        view.addSeparator()
        self.dock_action = self.dock.toggleViewAction()
        self.dock_action.setText("Parameter panel")
        view.addAction(self.dock_action)
        self._action(view, "Messages (every status bar message, whole)...", self.show_messages)
        self.picks_action = self.picks_panel.toggleViewAction()
        self.picks_action.setText("Picks (the points clicked, their XYZ, distance and angles)")
        view.addAction(self.picks_action)
        # The charts can go, giving their room to the views; double-clicking a view gives it the whole row (again:
        # the row back), as ParaView and CloudCompare do: the scene view had about 300 of 1,600 px (issue 45).
        self.charts_action = self._action(view, "Charts", self.toggle_charts, checkable=True)
        self.charts_action.setChecked(True)
        self._action(view, "Maximise the view under the mouse / all views (double-click a view)",
                     self._maximise_hovered)

        play = bar.addMenu("&Playback")
        self._action(play, "Play / pause", c.toggle_pause)
        self._action(play, "Step one unit", c.step)
        self.step_unit_menu = play.addMenu("Step unit")
        self._next_step_unit = self._action(self.step_unit_menu, "Next step unit", c.cycle_step_unit)
        self.step_unit_menu.aboutToShow.connect(self._fill_step_units)
        self._fill_step_units()
        self._action(play, "Faster (x2)", c.faster)
        self._action(play, "Slower (/2)", c.slower)
        windows = play.addMenu("Integration window")
        group = QtGui.QActionGroup(self)
        self.window_actions = {}
        for index, window in enumerate(WINDOWS):
            self.window_actions[window] = self._action(windows, window_label(window), lambda i=index: c.on_window(i),
                                                       checkable=True, group=group)
        self._action(windows, "Type a window...", self.type_window)
        windows.addSeparator()
        self._action(windows, "Next window", c.cycle_window)
        self._action(play, "Reset the scan to t = 0", c.reset)

        returns = bar.addMenu("&Returns")
        group = QtGui.QActionGroup(self)
        self.returns_actions = {model: self._action(returns, text, lambda m=model: c.set_returns_model(m),
                                                    checkable=True, group=group)
                                for model, text in (("ideal", "Ideal (each ray's exact first hit, as RflySim)"),
                                                    ("datasheet", "Datasheet (noise, footprint, returns, tags)"))}
        # The d key switches between the two: its own entry shows it, as v's does in the Pattern menu (a key is one
        # action's only shortcut, so neither choice above can hold it).
        self._action(returns, "Switch ideal / datasheet", c.toggle_returns_model)
        returns.addSeparator()
        self._action(returns, "Show the return model's sheet in the panel", c.toggle_slider_page)

        pattern = bar.addMenu("P&attern")
        self._action(pattern, "Switch rosette / track", c.toggle_pattern_model)
        self._action(pattern, "Random rotation after each flower / figure", c.toggle_jitter_scope)
        self._action(pattern, "Next preset", c.next_preset)
        self._action(pattern, "Previous preset", c.previous_preset)
        pattern.addSeparator()
        self._action(pattern, "Next reference preset", c.cycle_reference)
        self._action(pattern, "Reference overlay on / off", c.toggle_reference)
        self._action(pattern, "Reference's own window", c.cycle_reference_window)
        self._action(pattern, "Fit the rosette to the reference", c.fit_to_reference)
        self._action(pattern, "Cloud in the world / sensor frame", c.toggle_cloud_frame)

        helper = bar.addMenu("&Help")
        self._action(helper, "User guide...", self.open_guide)
        self._action(helper, "Keys and mouse", self.toggle_help)
        self._action(helper, "About livox-viz", self.about)

    def _make_scene_view_menus(self, view: QtWidgets.QMenu) -> None:
        """View > Projection, Viewpoints and Filters: the scene view's projection (ParaView's camera parallel
        projection), its saved cameras (ParaView's bookmarks, RViz's saved views) and its range and reflectivity
        filter (CloudCompare's filter by value, Livox Viewer's filters)."""
        c = self.controller
        projection = view.addMenu("Projection (scene view)")
        group = QtGui.QActionGroup(self)
        self.projection_actions = {
            name: self._action(projection, label, lambda p=name: c.set_projection(p), checkable=True, group=group)
            for name, label in zip(PROJECTIONS, ("Perspective", "Orthographic (parallel)"), strict=True)}
        projection.addSeparator()
        # The 5 key, shown here: a key is one action's only shortcut, so neither choice above can hold it.
        self._action(projection, "Switch perspective / orthographic", c.toggle_projection)
        self.viewpoints_menu = view.addMenu("Viewpoints (scene view)")
        self.viewpoints_menu.setToolTipsVisible(True)
        self.viewpoints_menu.aboutToShow.connect(self._fill_viewpoints)
        self._action(view, "Filters (range, reflectivity)...", self.open_filters)
        self._action(view, "Clear filters", c.clear_filters)
        self.filter_dialog: FilterDialog | None = None

    def _make_shortcuts(self) -> None:
        """Every key of the key table, window-wide (a spin box being typed in keeps its own keys)."""
        self.shortcuts: list[QtGui.QShortcut] = []
        for row in KEYS:
            for key, method in row.bindings:
                if key in self._menu_keys:  # its menu entry's action is its shortcut
                    continue
                shortcut = QtGui.QShortcut(key_sequence(key), self)
                shortcut.setContext(QtCore.Qt.ShortcutContext.WindowShortcut)
                target = getattr(self, method, None) or getattr(self.controller, method)
                shortcut.activated.connect(lambda t=target: self.run(t))
                self.shortcuts.append(shortcut)

    # Running actions ------------------------------------------------------------------------------
    def run(self, action: Callable[[], Any]) -> None:
        """Run a key's or menu's action: bad input becomes a message in the window, never a crash."""
        self._error_text = self.controller.guarded(action)
        if not self._closing:  # q closes the window: nothing left to bring up to date
            self._after_action()

    def _after_action(self) -> None:
        self.controller.refresh()
        self.panel.show_playback()  # the panel showed 1 x real time after Up had made it 10 x
        self._sync_menus()
        self._update_status()
        self._update_title()

    def say(self, text: str, error: bool = False) -> None:
        """A message in the status bar (red for an error, while it is the message)."""
        self.controller.session.message = text
        if error:
            self._error_text = text
        self._log(text, error)

    def _log(self, text: str, error: bool) -> None:
        """Keep ``text`` in the messages' log (and show it there if the log is open)."""
        message = self.messages.add(text, error)
        if message is not None and self.messages_dialog is not None and self.messages_dialog.isVisible():
            self.messages_dialog.append(message)

    def show_messages(self) -> None:
        """The messages' log beside the window, not modal, inside the screen (View > Messages, or a click on the
        status bar's message)."""
        if self.messages_dialog is None:
            self.messages_dialog = MessagesDialog(self.messages, self)
            self.messages_dialog.resize(*fit_to_screen(LOG_SIZE, self._available_area()))
        self.messages_dialog.refill()
        self.messages_dialog.show()
        self.messages_dialog.raise_()
        self.messages_dialog.activateWindow()

    @property
    def _error(self) -> bool:
        """Whether the status bar's message is a refusal or a failure (said red)."""
        return self._error_text is not None and self._error_text == self.controller.session.message

    def _defer(self, stages: set[str], action: Callable[[], None], what: str, kind: str = "config") -> bool:
        """The controller's gate: True when the loops of ``stages`` are loaded (run now); else ``action`` runs when
        they are, the window playing the current state meanwhile.

        One request waits per ``kind`` ("config", "returns", "reference"), the newest: a preset chosen while
        another waits replaces it, and one applied at once drops the one waiting (it would undo it later).
        """
        if self.warmer is None or self.warmer.is_ready(stages):
            self._pending.pop(kind, None)
            return True
        self._pending[kind] = (set(stages), action, what)
        self.say(self._waiting_text(stages, what))
        return False

    def _waiting_text(self, stages: set[str], what: str) -> str:
        """What a waiting change says: the loops it still waits for (fewer as the warm-up loads them)."""
        assert self.warmer is not None
        missing = sorted(set(stages) - self.warmer.ready)
        return (f"{what or 'the change'}: waiting for the {', '.join(missing)} loops; the current state plays "
                "meanwhile")

    def _run_deferred(self) -> None:
        if not self._pending or self.warmer is None:
            return
        for kind in ("config", "returns", "reference"):
            if kind not in self._pending:
                continue
            stages, action, what = self._pending[kind]
            failed = stages & set(self.warmer.failed)
            if failed:
                del self._pending[kind]
                stage = sorted(failed)[0]
                self.say(f"{what}: the {stage} loops could not be prepared ({self.warmer.failed[stage]})", error=True)
            elif self.warmer.is_ready(stages):
                del self._pending[kind]
                self.run(action)
                if not self._error:
                    self.say(f"{what}: ready" if what else "ready")
            else:
                # Some of its loops came in: the status bar, if it still says what this waits for, says it anew.
                text = self._waiting_text(stages, what)
                shown = self.controller.session.message
                if shown != text and shown.startswith(f"{what or 'the change'}: waiting for the "):
                    self.say(text)

    def _background(self, what: str, work: Callable[[], Any], done: Callable[[Any], None],
                    fraction: Callable[[], float] | None = None, cancel: Callable[[], None] | None = None) -> None:
        """Run ``work`` on a worker thread and ``done(result)`` on the UI thread after; the status bar shows it
        (with ``fraction()`` done as a percentage, when given). ``cancel``: gives the work up when the window
        closes."""
        future: Future = Future()

        def run() -> None:
            future.set_running_or_notify_cancel()
            try:
                future.set_result(work())
            except BaseException as exc:  # said in the window by _finish_jobs
                future.set_exception(exc)

        threading.Thread(target=run, daemon=True, name=f"livox-viz-{what.split()[0]}").start()
        self._jobs.append(_Job(what, future, done, time.monotonic(), fraction, cancel))

    def _finish_jobs(self) -> None:
        for job in [j for j in self._jobs if j.future.done()]:
            self._jobs.remove(job)
            try:
                result = job.future.result()
            except (LivoxVizError, OSError, ValueError, MemoryError) as exc:
                text = str(exc) if not isinstance(exc, OSError) else f"{exc.filename or ''}: {exc.strerror or exc}"
                self.say(f"{job.what} failed: {text}", error=True)
                continue
            self.run(lambda j=job, r=result: j.done(r))

    # The tick -----------------------------------------------------------------------------------
    def tick(self) -> None:
        """Advance the scan by the wall time passed, apply what became ready, redraw."""
        if self.none_reserve is not None:
            self.none_reserve.top_up()
        self.collector.collect_due()
        if self._stop is not None and self._stop():
            self.close()
            return
        warmer = self.warmer
        if warmer is not None and not self.controller.session.casting:
            pattern = set(warmer.now) - {"ideal", "datasheet", "motion"}
            if not self._playing_allowed and warmer.is_ready(pattern):
                self._playing_allowed = True
                self.controller.session.playback.restart()
            failed = set(warmer.now) & set(warmer.failed)
            if failed:
                self.say(f"the ray caster could not be prepared: {next(iter(warmer.failed.values()))}", error=True)
            elif warmer.is_ready(warmer.now):
                self._playing_allowed = True
                self.controller.session.start_casting()
        self._finish_jobs()
        self._run_deferred()
        self._trim_after_restarts()
        if self._history_shown != self.controller.session.history.version:  # a change from the panel, say
            self._sync_history()
        session = self.controller.session
        if session.source is not None and session.playback.paused:
            # A paused live view still reads the stream (a resting window ticks no further): the status bar's rates
            # stay true, and play resumes with the stream as it is. A trial saw "no frame for 2 s" while frames
            # came, then double the rate on play (a burst of the frames that had waited).
            session.set_aside_arrivals()
            line = session.live_line()
            if line != self._live_shown:
                self._live_shown = line
                self._update_status()
        if self._resting():
            return
        try:
            if self._playing_allowed:
                self.controller.tick()
            else:
                self.controller.refresh()
        except LivoxVizError as exc:
            self.say(str(exc), error=True)
        self._follow_view_sizes()
        self.controller.render(draw=QtWidgets.QWidget.update)
        if self._first_frame is None and self._playing_allowed:
            self._first_frame = time.perf_counter() - self.opened
        if warmer is not None and not warmer.started:  # after the first frame: see widgets/warmup.py
            warmer.start()
        self._update_status()

    def _trim_after_restarts(self) -> None:
        """A second after a restart (a preset, a scene, a parameter, a fit taken), the heap's free pages go back to
        the system (:func:`~livox_viz.widgets.collector.give_back_free_memory`): once per restart, not per tick."""
        number = self.controller.session.scan_number
        if number != self._trimmed_scan:
            self._trimmed_scan = number
            self._trim_due = time.monotonic() + 1.0
        elif self._trim_due is not None and time.monotonic() >= self._trim_due:
            self._trim_due = None
            self.memory_trims += give_back_free_memory()

    def _resting(self) -> bool:
        """True when the window is paused and nothing changed since the last tick: nothing is brought up to date or
        drawn (paused, it used a whole core redrawing the same picture 10-14 times a second; issue 45).

        "Nothing changed" is the scan's state (its number, time, configuration, message, the points its rings
        hold and the casts still coming in), the window's and the views' sizes, the jobs and deferred changes,
        and every input event the application took (a key, a click, the wheel: a menu, a box or a view's camera
        may have changed something the views draw). The views' own mouse interaction is drawn by VTK itself.
        """
        session = self.controller.session
        warmer = self.warmer
        if not (self._playing_allowed and session.playback.paused) or self._jobs or self._pending \
                or session.filling is not None or (warmer is not None and not warmer.is_ready(warmer.now)):
            self._rest_signature = None
            return False
        # The rings' counts: casts finished after the pause still come in (and the time window drops old points).
        signature = (session.scan_number, session.scan_time, id(session.config), session.message, self._inputs,
                     self.size().toTuple(), tuple(self.splitter.sizes()), self._error_text,
                     session.pattern_ring.count, session.scene_ring.count)
        if signature == self._rest_signature:
            return True
        self._rest_signature = signature  # drawn once more, then at rest
        return False

    def eventFilter(self, watched: QtCore.QObject, event: QtCore.QEvent) -> bool:
        """Counts the application's input events (see :meth:`_resting`), and a double-click on a view maximises it
        (or brings the others back); never takes an event."""
        if event.type() in _INPUT_EVENTS:
            self._inputs += 1
            if event.type() == QtCore.QEvent.Type.MouseButtonDblClick and watched in self.interactors.values():
                self.toggle_maximised(watched)
        return False

    @property
    def maximised(self) -> str | None:
        """The view that has the whole row (its name), or None when every view shown has its share."""
        shown = [name for name, view in self.interactors.items() if not view.isHidden()]
        return shown[0] if len(shown) == 1 and len(self.interactors) > 1 else None

    def toggle_maximised(self, view: QtWidgets.QWidget) -> None:
        """``view`` alone in the row, or, when it already is, every view back (the charts as the menu says)."""
        name = next(name for name, widget in self.interactors.items() if widget is view)
        if self.maximised == name:
            for other, widget in self.interactors.items():
                widget.setVisible(other != "charts" or self.charts_action.isChecked())
            self.say("every view back (double-click a view to give it the whole row)")
        else:
            for other, widget in self.interactors.items():
                widget.setVisible(other == name)
            self.say(f"the {name} view maximised (double-click it again for every view)")

    def _maximise_hovered(self) -> None:
        """The menu's way to :meth:`toggle_maximised`: the view under the mouse, else the scene view."""
        under = QtWidgets.QApplication.widgetAt(QtGui.QCursor.pos())
        view = next((widget for widget in self.interactors.values()
                     if under is not None and (under is widget or widget.isAncestorOf(under))),
                    self.interactors.get("scene"))
        if view is not None:
            self.toggle_maximised(view)

    def toggle_charts(self) -> None:
        """Hide the charts (their room goes to the other views) or show them again."""
        shown = self.charts_action.isChecked()
        charts = self.interactors.get("charts")
        if charts is not None and self.maximised is None:
            charts.setVisible(shown)
        self.say("charts shown" if shown else "charts hidden (View > Charts shows them)")

    def _follow_view_sizes(self) -> None:
        """Refit the pattern view when its size changed (the window or a splitter moved): the field of view stays
        whole in it. The first time, share the width 5 : 4 : 3 among the views."""
        if not self._sized and self.splitter.width() > 600:
            self._sized = True
            total = sum(self.splitter.sizes())
            self.splitter.setSizes([total * 5 // 12, total * 4 // 12, total - total * 9 // 12])
        view = self.controller.pattern_view
        if view is not None:
            size = tuple(view.renderer.GetSize())
            if size != self._pattern_size:
                self._pattern_size = size
                view.reset_camera()
                view.refit_guides()

    # Status, title, menus -------------------------------------------------------------------------
    def _update_title(self) -> None:
        self.setWindowTitle(f"livox-viz - {self.controller.session.preset_name or 'custom'}")

    def _update_status(self) -> None:
        session = self.controller.session
        state = "paused" if session.playback.paused else f"{session.playback.speed:g}x"
        self.status_time.setText(f"t = {session.shown_time:.3f} s ({state})")
        held = session.pattern_ring.count
        fired = session.points_fired_in_window()
        self.status_points.setText(f"window {window_label(session.window)}: {held:,} of {fired:,} points")
        self.status_fps.setText(f"{self.controller.fps:4.1f} fps")
        self.status_returns.setText(f"returns: {session.config.returns_model}")
        busy = [job.describe() for job in self._jobs]
        if self.warmer is not None and self.warmer.working:
            busy.append(self.warmer.describe())
        if not self.controller.session.casting:
            busy.append("starting the ray caster (the pattern plays)")
        if self.controller.fitting and "fitting" not in session.message:  # the message says it already
            busy.append(f"fitting to {self.controller.fitting}")
        if session.filling is not None:
            busy.append(f"filling the window {100 * session.filling:.0f} %")
        self.busy.setVisible(bool(busy))
        self.status_busy.setText("; ".join(b for b in busy if b))
        message = session.message
        if self.controller.pick_text and not message:
            message = self.controller.pick_text
        if session.live is not None and not message:  # where it listens, who sends, how fast, or that it stopped
            message = session.live_line()
        self.status_message.setText(message)
        # Messages the controller and its threads set (a screenshot saved, a pick) are kept as they are shown.
        self._log(message, self._error and message == session.message)
        self.status_message.setStyleSheet("color: #d9534f;" if self._error and message else "")
        self._share_status_room()
        paused = session.playback.paused
        self.scrubber.setEnabled(paused and self._played > 0)
        # Playing, it shows where the scan is too (at its end): it sat at 0 until the first pause.
        if not self.scrubber.held:  # held, the bar shows the time of the handle
            if self._played > 0:
                with signals_blocked(self.scrubber):
                    self.scrubber.setValue(round(1000 * session.shown_time / self._played))
            self.scrub_label.setText(f" scan time {session.shown_time:8.3f} s ")

    def _share_status_room(self) -> None:
        """What is being prepared gets the room the permanent figures leave, but for the message's share: the
        message's own width, up to 300 px or 40 % of the room (none when there is no message)."""
        busy, message = self.status_busy, self.status_message
        if not busy.isVisible() or not message.isVisible():
            return
        spacing = max(self.statusBar().layout().spacing(), 0)
        room = message.geometry().right() - busy.geometry().left() + 1 - spacing
        share = min(message.sizeHint().width(), max(STATUS_MESSAGE_SHARE, int(0.4 * room))) if message.text() else 0
        busy.set_widest(max(room - share, busy.minimumSizeHint().width()))

    def _sync_menus(self) -> None:
        session = self.controller.session
        for mode, action in self.scene_colour_actions.items():
            action.setChecked(mode == session.display.scene_colour)
        for mode, action in self.drawing_actions.items():
            action.setChecked(mode == session.display.drawing)
        for window, action in self.window_actions.items():
            action.setChecked(window == session.window)
        for model, action in self.returns_actions.items():
            action.setChecked(model == session.config.returns_model)
        pattern_view = self.controller.pattern_view
        if pattern_view is not None:  # what the keys change too: each submenu checks what is shown
            for name, action in self.colour_map_actions.items():
                action.setChecked(name == pattern_view.colour_map)
            for pixels, action in self.point_size_actions.items():
                action.setChecked(pixels == pattern_view.point_size)
            for name, action in self.background_actions.items():
                action.setChecked(name == pattern_view.background_name)
        view = self.controller.scene_view
        if view is not None:
            self.follow_action.setChecked(view.follow)
            for name, action in self.projection_actions.items():
                action.setChecked(name == view.projection)
        self._sync_history()

    def _sync_history(self) -> None:
        """The Edit menu names the change an undo or a redo would make, and offers neither when there is none."""
        session = self.controller.session
        self._history_shown = session.history.version
        for action, word, target in ((self.undo_action, "Undo", session.history.undo_target()),
                                     (self.redo_action, "Redo", session.history.redo_target())):
            if target is None:
                action.setText(word)
            else:
                current = session.state
                change = (describe_change(target, current) if word == "Undo" else describe_change(current, target))
                action.setText(f"{word} {short_description(change)}")
            action.setEnabled(target is not None)

    @staticmethod
    def _cleared(menu: QtWidgets.QMenu) -> QtGui.QActionGroup:
        """``menu`` emptied and the group of its last entries deleted (one more group each time the menu opened);
        a new group for its entries."""
        menu.clear()
        for group in menu.findChildren(QtGui.QActionGroup, options=QtCore.Qt.FindChildOption.FindDirectChildrenOnly):
            group.setParent(None)
            group.deleteLater()
        return QtGui.QActionGroup(menu)

    def _fill_pattern_colours(self) -> None:
        """The pattern colourings the configuration has (they differ by model), then the c key's entry."""
        menu = self.pattern_colour_menu
        group = self._cleared(menu)
        current = self.controller.session.display.pattern_colour
        for mode in pattern_colours(self.controller.session.config):
            action = self._action(menu, mode, lambda m=mode: self.controller.set_pattern_colour(m), checkable=True,
                                  group=group)
            action.setChecked(mode == current)
        menu.addSeparator()
        menu.addAction(self._next_pattern_colour)

    def _fill_step_units(self) -> None:
        """The step units the configuration has, then the u key's entry."""
        menu = self.step_unit_menu
        group = self._cleared(menu)
        display = self.controller.session.display
        for unit in step_units(self.controller.session.config):
            action = self._action(menu, unit, lambda u=unit: setattr(display, "step_unit", u), checkable=True,
                                  group=group)
            action.setChecked(unit == display.step_unit)
        menu.addSeparator()
        menu.addAction(self._next_step_unit)

    def _fill_presets(self, menu: QtWidgets.QMenu) -> None:
        """The presets by name and the start of their description, the whole of it in the entry's tooltip: whole,
        the entries ran past a 1600-pixel screen. The one shown is checked."""
        group = self._cleared(menu)
        menu.setToolTipsVisible(True)
        current = self.controller.session.preset_name
        for info in list_presets():
            action = self._described_action(menu, info.name, info.description,
                                            lambda i=info: self.load_preset_file(i.path, i.name), group)
            action.setChecked(info.name == current)

    def _described_action(self, menu: QtWidgets.QMenu, name: str, description: str, slot: Callable[[], Any],
                          group: QtGui.QActionGroup | None = None) -> QtGui.QAction:
        """An entry named ``name`` and the start of ``description``, the whole of it in its tooltip (checkable in
        ``group`` when one is given)."""
        label = f"{name}  ({short_description(description)})" if description else name
        action = self._action(menu, label, slot, checkable=group is not None, group=group)
        action.setToolTip(description)
        return action

    def _fill_tables(self, menu: QtWidgets.QMenu) -> None:
        """The scan tables livox-viz ships, by name (the file dialog wanted their path, which a user cannot know);
        a table of another plane than the configuration's is shown but not offered."""
        from livox_viz import load_preset
        from livox_viz.fitting.reference import shipped_tables

        self._cleared(menu)
        menu.setToolTipsVisible(True)
        plane = self.controller.session.config.pattern_plane
        for name, entry in shipped_tables().items():
            description = entry.get("description", "")
            action = self._described_action(menu, name, description, lambda n=name: self.load_reference(n))
            try:
                table_plane = load_preset(entry["preset"]).pattern_plane
            except (KeyError, LivoxVizError, OSError):
                continue
            if table_plane != plane:
                action.setEnabled(False)
                action.setToolTip(f"{description} ({table_plane} plane; this configuration's is {plane})")

    def _fill_scenes(self, menu: QtWidgets.QMenu) -> None:
        from livox_viz.scene.scenes import scene_choices

        group = self._cleared(menu)
        session = self.controller.session
        current = session.sources.get("scene") or session.scene.name
        for choice in scene_choices():
            action = self._action(menu, Path(choice).name if os.sep in choice else choice,
                                  lambda c=choice: self.load_scene(c), checkable=True, group=group)
            action.setChecked(choice == current)  # the scene shown

    def _fill_viewpoints(self) -> None:
        """View > Viewpoints, read afresh from the file each time it opens (another window may have saved one):
        save, the saved ones to restore, delete. A file that cannot be read (all or some of it) is one line in the
        status bar; what could be read is offered."""
        menu = self.viewpoints_menu
        menu.clear()
        self._action(menu, "Save current view...", self.save_viewpoint)
        book = read_viewpoints()
        if book.problem:
            self.say(book.problem, error=True)
            self._update_status()
        menu.addSeparator()
        if not book.viewpoints:
            empty = menu.addAction("no viewpoints saved" if not book.problem else "no viewpoint could be read")
            empty.setEnabled(False)
        for viewpoint in book.viewpoints:
            camera = viewpoint.camera
            # A name's & would be read as a mnemonic's mark and vanish from the entry.
            action = self._action(menu, viewpoint.name.replace("&", "&&"),
                                  lambda v=viewpoint: self.controller.restore_scene_camera(v.camera, v.name))
            action.setToolTip(f"{camera.projection}, looking from ({', '.join(f'{v:.1f}' for v in camera.position)}) "
                              f"at ({', '.join(f'{v:.1f}' for v in camera.focal_point)}), m")
        if book.viewpoints:
            menu.addSeparator()
            delete = menu.addMenu("Delete")
            for viewpoint in book.viewpoints:
                self._action(delete, viewpoint.name.replace("&", "&&"),
                             lambda n=viewpoint.name: self.delete_viewpoint(n))

    def save_viewpoint(self, name: str | None = None) -> None:
        """View > Viewpoints > Save current view: the scene view's camera under a name the user gives, in the
        viewpoints file (a name taken replaces its viewpoint, and says so)."""
        if name is None:
            taken = read_viewpoints().names()
            suggestion = next(f"view {k}" for k in range(1, len(taken) + 2) if f"view {k}" not in taken)
            name, accepted = QtWidgets.QInputDialog.getText(
                self, "Save the scene view", f"Name of this viewpoint (1 to {NAME_CHARS} characters; a name "
                "taken is replaced):", QtWidgets.QLineEdit.EchoMode.Normal, suggestion)
            if not accepted:
                return
        self.say(save_viewpoint(name, self.controller.scene_camera()))

    def delete_viewpoint(self, name: str) -> None:
        self.say(delete_viewpoint(name))

    def open_filters(self) -> None:
        """View > Filters: the dialog of the scene view's range and reflectivity bounds, beside the window."""
        if self.filter_dialog is None:
            view = self.controller.scene_view
            if view is None:
                raise LivoxVizError("no scene view to filter; allowed: the window with its scene view")

            def apply(cloud_filter):
                self.run(lambda: self.controller.set_cloud_filter(cloud_filter))
                return self._error_text if self._error else None

            def refuse(text: str) -> None:
                self.say(text, error=True)
                self._after_action()

            self.filter_dialog = FilterDialog(self, lambda: view.cloud_filter, apply, refuse)
        self.filter_dialog.show_current()
        self.filter_dialog.show()
        self.filter_dialog.raise_()
        self.filter_dialog.activateWindow()

    def _panel_follow(self) -> None:
        self.panel.follow()
        self._update_title()

    # Actions the window adds to the controller's --------------------------------------------------
    def quit(self) -> None:
        self.close()

    def toggle_help(self) -> None:
        """The keys and the mouse, in a dialog beside the window (h)."""
        if self.help_dialog is None:
            dialog = _HelpDialog(self)
            dialog.setObjectName("help")
            dialog.setWindowTitle("livox-viz - keys and mouse")
            text = QtWidgets.QTextBrowser(dialog)
            text.setHtml(help_html())
            layout = QtWidgets.QVBoxLayout(dialog)
            layout.addWidget(text)
            # A button as well as h and Esc: a trial found no way to close it with the mouse without a title bar.
            buttons = QtWidgets.QDialogButtonBox(QtWidgets.QDialogButtonBox.StandardButton.Close, dialog)
            buttons.rejected.connect(dialog.hide)
            layout.addWidget(buttons)
            dialog.resize(min(760, self.width() - 40), min(640, self.height() - 40))
            self.help_dialog = dialog
        if self.help_dialog.isVisible():
            self.help_dialog.hide()
        else:
            self.help_dialog.show()
            self.help_dialog.raise_()

    def open_guide(self) -> None:
        """The user guide (docs/), beside the window and not modal, sized to fit the screen (Help > User guide)."""
        if self.guide is None:
            folder = guide_dir()
            if folder is None:
                self.say("the user guide is not part of this installation of livox-viz", error=True)
                return
            self.guide = UserGuide(folder, self)
            self.guide.resize(*fit_to_screen(GUIDE_SIZE, self._available_area()))
        self.guide.show()
        self.guide.raise_()
        self.guide.activateWindow()

    def about(self) -> None:
        from livox_viz import __version__

        QtWidgets.QMessageBox.about(self, "About livox-viz", f"livox-viz {__version__}: a visualizer and pattern "
                                    "tuner for RflySim's simulated Livox lidars.")

    def set_colour_map(self, name: str) -> None:
        for view in (self.controller.pattern_view, self.controller.scene_view):
            if view is not None:
                view.set_colour_map(name)
        self.say(f"colour map {name}")

    def set_point_size(self, pixels: float) -> None:
        for view in (self.controller.pattern_view, self.controller.scene_view):
            if view is not None:
                view.set_point_size(pixels)
        self.say(f"point size {pixels:g} px")

    def set_background(self, name: str) -> None:
        for view in (self.controller.pattern_view, self.controller.scene_view):
            if view is not None:
                view.set_background(name)

    def set_drawing(self, mode: str) -> None:
        self.controller.session.display.drawing = mode
        self.say(f"drawing: {mode}")

    def toggle_grid(self) -> None:
        view = self.controller.scene_view
        view.show_grid(view.grid_actor is None)
        self.grid_action.setChecked(view.grid_actor is not None)

    def toggle_axes(self) -> None:
        view = self.controller.scene_view
        view.show_axes(view.axes_actor is None)
        self.axes_action.setChecked(view.axes_actor is not None)

    def ask_seconds(self, title: str, question: str, value: float, low: float, high: float,
                    decimals: int) -> float | None:
        """Seconds from a dialog, from ``low`` to ``high``; None if cancelled.

        A number outside is refused and asked for again, the dialog saying why. Given Qt's own range, its box
        dropped the keystroke that left it: "200" against 120 became 20, and a 20 s bag was written without a word.
        """
        note = ""
        while True:
            value, accepted = QtWidgets.QInputDialog.getDouble(
                self, title, f"{note}{question} ({low:g} to {high:g}):", value, -1e9, 1e9, decimals)
            if not accepted:
                return None
            if low <= value <= high:
                if note and self._error:  # the refusal is answered: its red line would outlive it
                    self.say("")
                return value
            note = f"{value:g} s refused: allowed {low:g} to {high:g} s.\n"
            self.say(f"{title}: {value:g} s refused; allowed: {low:g} to {high:g} s", error=True)
            value = min(max(value, low), high)

    def type_window(self) -> None:
        value = self.ask_seconds("Integration window", "seconds", self.controller.session.window or 1.0, 0.01, 10.0,
                                 3)
        if value is not None:
            self.controller.set_window_seconds(value)

    def _picks_follow(self) -> None:
        """The Picks panel shows the controller's picks; it opens at the first pick of a list (after a Clear or a
        restart too), as a user closed it stays closed while the list goes on."""
        panel = self.picks_panel
        picks = self.controller.picks
        opening = len(picks) == 1 and self._picks_shown == 0 and panel.isHidden()
        self._picks_shown = len(picks)
        panel.follow()
        if opening:
            panel.show()
            # A share of the height the views can spare: at 1280 x 720 they keep 240 px and more.
            self.resizeDocks([panel], [min(PICKS_PANEL_HEIGHT, max(self.height() // 4, 120))],
                             QtCore.Qt.Orientation.Vertical)

    def type_colour_range(self) -> None:
        """View > Colour range: the scene colour bar's min and max as typed (a refused pair is said and asked
        again), or Automatic, the data's range."""
        session = self.controller.session
        mode = session.display.scene_colour
        if mode not in RANGE_UNITS:
            raise LivoxVizError(f"the {mode} colouring is classes, not a scale: it has no colour range; allowed: "
                                f"{', '.join(RANGE_UNITS)} (View > Colour the cloud by)")
        values = tuple(f"{v:g}" for v in session.scene_scalar_range())
        refusal = ""
        while True:
            answer = ColourRangeDialog.ask(self, mode, RANGE_UNITS[mode], values,
                                           session.scene_scalar_range(automatic=True), refusal)
            if answer is None:
                if refusal:
                    raise LivoxVizError(refusal)  # the last word on it stays, red
                return
            if answer == AUTOMATIC:
                self.controller.automatic_colour_range()
                return
            values = answer
            try:
                self.controller.set_colour_range(*answer)
            except LivoxVizError as exc:
                refusal = str(exc)
                self.say(refusal, error=True)
                continue
            return

    def pick(self, view: str, x: int, y: int) -> None:
        """A click on a view: the point picked, in the status bar."""
        self.controller.session.message = ""
        if view == "scene":
            self.controller.pick_scene(x, y)
        else:
            self.controller.pick_pattern(x, y)
        self._update_status()

    def _scrub_moved(self, value: int) -> None:
        if not self.scrubber.held:  # a key or setValue: sought at once
            self._scrubbed()
            return
        # Held, the handle shows the time it is at, beside the bar and in a tip that follows it (a first-use trial
        # saw nothing change while dragging); the window is cast again when it is let go.
        text = f" scan time {value / 1000 * self._played:8.3f} s "
        self.scrub_label.setText(text)
        handle = self.scrubber.handle_rect()
        # Above the handle (Qt puts a tip below the point it is given): below, it covered the status bar's clock.
        above = QtCore.QPoint(handle.center().x(), handle.top() - 2 * handle.height() - 8)
        QtWidgets.QToolTip.showText(self.scrubber.mapToGlobal(above), f"t = {value / 1000 * self._played:.3f} s",
                                    self.scrubber)

    def _scrubbed(self) -> None:
        QtWidgets.QToolTip.hideText()
        session = self.controller.session
        target = self.scrubber.value() / 1000 * self._played
        if session.shown_time == target:  # the handle let go where it was: nothing to cast again
            return
        # The picks belonged to the time left behind (a trial found them floating over another time's cloud).
        self.run(lambda: (session.seek(target), self.controller.forget_picks()))

    # Files ---------------------------------------------------------------------------------------
    def _ask_open(self, title: str, filters: str) -> str | None:
        path, _ = QtWidgets.QFileDialog.getOpenFileName(self, title, str(Path.cwd()), filters)
        return path or None

    def open_config(self, path: str | None = None) -> None:
        """File > Open sensor config or preset: a RflySim sensor JSON (or Config.json), checked before it is used."""
        path = path or self._ask_open("Open a sensor configuration", "Sensor JSON (*.json);;All files (*)")
        if path:
            self.load_preset_file(Path(path), Path(path).stem)

    def load_preset_file(self, path: Path, name: str) -> None:
        config = load_config(path)  # a broken file raises here: the window keeps what it had
        if self.controller.apply_config(config, name, f"{name}"):
            self.say(f"opened {name}")

    def save_config_as(self, path: str | None = None) -> None:
        """Write the configuration in use as a sensor JSON RflySim reads."""
        session = self.controller.session
        if path is None:
            # A name to start from, as the exports have: the preset's, marked when its values were changed.
            name = Path(session.preset_name).name.removesuffix(".json") if session.preset_name else "sensor"
            if session.preset_config is not None and session.config != session.preset_config:
                name += "_tuned"
            path, _ = QtWidgets.QFileDialog.getSaveFileName(self, "Save the configuration",
                                                            str(Path.cwd() / f"{name}.json"), "Sensor JSON (*.json)")
        if path:
            target = Path(path if path.lower().endswith(".json") else path + ".json")
            save_config(session.config, target)
            self.say(f"saved {target}")

    def open_scene(self, path: str | None = None) -> None:
        """File > Open scene or mesh: loaded and its caster built on a worker; the old scene plays meanwhile."""
        path = path or self._ask_open("Open a scene or mesh",
                                      "Scenes and meshes (*.json *.obj *.stl *.ply *.glb *.gltf *.off);;All files (*)")
        if path:
            self.load_scene(path)

    def cycle_scene(self) -> None:
        """The m key: the next scene, loaded on a worker (a large mesh takes seconds); the old one plays meanwhile."""
        self.load_scene(self.controller.next_scene_choice())

    def load_scene(self, choice: str) -> None:
        from livox_viz.scene.raycast import EmbreeCaster
        from livox_viz.scene.scenes import open_scene

        options = dict(self.controller.session.scene_options)

        def work():
            scene = open_scene(choice, **options)
            return scene, EmbreeCaster(scene.mesh)

        def done(result) -> None:
            scene, caster = result
            self.controller.session.set_scene(scene, caster)
            self.controller.session.sources["scene"] = choice
            self.say(f"scene {scene.name}")

        self._background(f"loading {Path(choice).name}", work, done)

    def open_reference(self, path: str | None = None) -> None:
        """File > Open reference: a scan table (.npy, .npz, Livox CSV), a real sensor's recording (.pcd, .ply, a CSV
        of x, y, z, .lvx2, .lvx, .bag) or a preset file, read on a worker."""
        path = path or self._ask_open("Open a reference",
                                      "Tables, recordings and presets (*.npy *.npz *.csv *.pcd *.ply *.lvx2 *.lvx "
                                      "*.bag *.json);;All files (*)")
        if path:
            self.load_reference(path)

    def load_reference(self, text: str) -> None:
        from .commands import reference_source

        seed = self.controller.session.seed
        rate = float(self.controller.session.config.point_rate)  # a recording without times is at the head's rate

        def done(source: TableSource | PresetSource) -> None:
            self.controller.set_reference(source)
            self.controller.session.sources["reference"] = text

        def work() -> TableSource | PresetSource:
            import argparse

            from .commands import _check_reference

            source = reference_source(text, None, seed, rate)
            # As --reference is checked: a table too short to compare, or one whose windows outgrow the budget.
            _check_reference(source, argparse.Namespace(reference=text, reference_rate=None))
            return source

        self._background(f"reading {Path(text).name}", work, done)

    def open_cloud(self, path: str | None = None) -> None:
        """File > Open cloud: a point cloud file read on a worker and drawn in the scene view beside the scan's,
        static, in light grey (see :mod:`livox_viz.files.cloud_file` for the formats and frames)."""
        path = path or self._ask_open("Open a cloud to draw beside the scan",
                                      "Point clouds (*.ply *.pcd *.las *.laz *.npz *.csv *.lvx2 *.lvx *.bag "
                                      "metadata.yaml);;All files (*)")
        if path:
            self.load_cloud(path)

    def load_cloud(self, text: str) -> None:
        """Read the cloud ``text`` on a worker; a world-frame file is drawn as written (world NED), a sensor-frame
        one (our sensor exports, a recording in Livox's frame) placed with the sensor's pose as the window opened
        it, as the scan's sensor-frame points are."""
        from livox_viz.files.cloud_file import read_cloud

        if self.controller.scene_view is None:
            raise LivoxVizError("no scene view to draw a cloud in; allowed: the window with its scene view")
        pose = self.controller.session.sensor_pose  # the sensor now: where a sensor-frame cloud is placed

        def work():
            cloud = read_cloud(text)
            points = cloud.points_m if cloud.frame == "world" else pose.origin + cloud.points_m @ pose.rotation.T
            return cloud, points.astype(np.float32)

        def done(result) -> None:
            cloud, points = result
            self.controller.forget_opened_cloud_picks()
            self.controller.scene_view.show_opened_cloud(points, cloud.name)
            where = ("drawn as written, in the world frame" if cloud.frame == "world" else
                     "in the sensor's frame, placed at the sensor's pose now")
            self.say(f"opened cloud {cloud.name}: {len(points):,} points ({cloud.source}), {where}")

        self._background(f"reading {Path(text).name}", work, done)

    def close_cloud(self) -> None:
        """File > Close cloud: the opened cloud leaves the scene view."""
        view = self.controller.scene_view
        if view is None or view.opened is None:
            self.say("no cloud is open (File > Open cloud)")
            return
        name = view.opened[0]
        self.controller.forget_opened_cloud_picks()
        view.show_opened_cloud(None)
        self.say(f"closed cloud {name}")

    def export_cloud(self, suffix: str, path: str | None = None) -> None:
        """File > Export: the window's cloud, cast again from its stream on a worker into the file by the writers
        of ``livox-viz scan`` (the same points the window shows, at full precision)."""
        session = self.controller.session
        if session.source is not None:
            raise LivoxVizError("a live view's cloud is not exported here; record it with 'livox-viz listen "
                                "--record FILE'")
        if path is None:
            path, _ = QtWidgets.QFileDialog.getSaveFileName(self, "Export the window's cloud",
                                                            str(Path.cwd() / f"window{suffix}"), f"*{suffix}")
        if not path:
            return
        target = Path(path if path.lower().endswith(suffix) else path + suffix)
        work = files.window_export(session, target)
        self._background(f"exporting {target.name}", work, lambda count: self.say(f"exported {count:,} points to "
                                                                                   f"{target}"))

    def export_bag(self, path: str | None = None, seconds: float | None = None) -> None:
        """File > Export ROS 2 bag: the scan from t = 0 of the window's configuration, return model, scene, pose,
        motion and seed, for the seconds the user asks, into the bag ``livox-viz scan --rosbag`` writes for them
        (its topics and messages: CustomMsg, PointCloud2, Imu, Odometry, /tf); written on a worker, atomically."""
        session = self.controller.session
        if session.source is not None:
            raise LivoxVizError("a live view is not exported as a bag here; record it with 'livox-viz listen "
                                "--record FILE'")
        longest = math.floor(100 * files.bag_longest(session)) / 100  # as the box shows it, to its two decimals
        if seconds is None:
            seconds = self.ask_seconds("Export a ROS 2 bag", "scan seconds from t = 0",
                                       min(files.BAG_SECONDS, longest), files.BAG_SHORTEST, longest, 2)
            if seconds is None:
                return
        if path is None:
            name = f"{session.preset_name or 'custom'}_{seconds:g}s_bag"
            path, _ = QtWidgets.QFileDialog.getSaveFileName(self, "Export a ROS 2 bag (a new folder)",
                                                            str(Path.cwd() / name), "ROS 2 bag folder (*)")
        if not path:
            return
        target = files.check_bag_folder(Path(path))
        work = files.BagExport(session, target, seconds)

        def done(written) -> None:
            self.say(f"exported a {seconds:g} s bag ({written.frames} frames, {written.points:,} points) to {target}")

        self._background(f"exporting {target.name}", work, done, fraction=lambda: work.fraction, cancel=work.cancel)

    # Closing -------------------------------------------------------------------------------------
    def closeEvent(self, event: QtGui.QCloseEvent) -> None:
        if self._closing:
            event.accept()
            return
        self._closing = True
        self.timer.stop()
        app = QtWidgets.QApplication.instance()
        if app is not None:
            app.removeEventFilter(self)
        # A bag being written is given up (nothing is kept) rather than left half-made by the process's end.
        for job in self._jobs:
            if job.cancel is not None:
                job.cancel()
        for job in self._jobs:
            if job.cancel is not None:
                try:
                    job.future.exception(timeout=CANCEL_WAIT_S)
                except TimeoutError:
                    pass
        if self.warmer is not None:
            self.warmer.close()
        if self.help_dialog is not None:
            self.help_dialog.close()
        if self.filter_dialog is not None:
            self.filter_dialog.close()
        if self.guide is not None:
            self.guide.close()
        if self.messages_dialog is not None:
            self.messages_dialog.close()
        self.controller.close()
        release_gl_wrappers(self.interactors.values())  # each view's GL is finalized by now
        self.collector.stop()
        event.accept()


class _HelpDialog(QtWidgets.QDialog):
    """The keys' dialog: h closes it from the dialog too (it has the focus once shown; a first-use run pressed h
    again there and it stayed), as Esc does."""

    def keyPressEvent(self, event: QtGui.QKeyEvent) -> None:
        if event.key() == QtCore.Qt.Key.Key_H and event.modifiers() == QtCore.Qt.KeyboardModifier.NoModifier:
            self.hide()
            return
        super().keyPressEvent(event)


#: Pixels a window manager's title bar and frame take around the window, at most, on the screens we know.
FRAME_ALLOWANCE = (16, 48)


def fit_to_screen(size: tuple[int, int], available: tuple[int, int] | None) -> tuple[int, int]:
    """``size`` (pixels), made no larger than the screen's ``available`` area (its size without task bars and
    docks; None: not known) less :data:`FRAME_ALLOWANCE`: the window opened at 1600x900 on a 1280x720 screen, its
    charts, status bar (where refusals and picks are said), scrubber and speed box off the screen (issue 45)."""
    if available is None:
        return size
    return (max(64, min(size[0], available[0] - FRAME_ALLOWANCE[0])),
            max(64, min(size[1], available[1] - FRAME_ALLOWANCE[1])))


def run_window(session: Session, size: tuple[int, int], stop: Callable[[], bool] | None = None,
               warmer: LoopWarmer | None = None) -> int:
    """Open the window and run until it is closed (or ``stop()`` is true); the Qt event loop's status.

    ``warmer``: the compiled loops' loader, made by the caller (else the window makes one); started after the
    first frame.
    """
    app = application()
    window = MainWindow(session, size=size, stop=stop, warmer=warmer)
    window.show()
    status = int(app.exec())
    destroy_widget_tree(window)  # now, with nothing collected midway: see widgets/collector.py
    return status
