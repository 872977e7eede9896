"""The two linked views: the pattern in the angular plane, and the scan cast into the 3D scene.

Each view adds its actors once and afterwards only marks the ring's arrays
modified and re-points its vertex cells at the live slots (see
:class:`~livox_viz.widgets.ring.PointRing`): no actor is re-created on a tick.
Each view subscribes to the session and redraws what depends on the
configuration, the scene or the vehicle pose whenever one of them changes.
"""

from __future__ import annotations

import math

import numpy as np
import pyvista as pv
from vtkmodules.vtkCommonCore import vtkPoints, vtkStringArray, vtkUnsignedCharArray
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
from vtkmodules.vtkRenderingCore import vtkActor2D, vtkPolyDataMapper2D, vtkTextActor, vtkTextRenderer

from livox_viz.core.errors import LivoxVizError
from livox_viz.core.rotations import FRD_TO_FLU

from .cameras import PROJECTIONS, distance_for, fit_parallel, parallel_scale_for, screen_axes
from .filters import CloudFilter, filtered_slots
from .ring import PointRing
from .session import PATTERN_COLOURS, TAG_CLASSES, Session, pattern_colours

#: NED (z down) to the display's z-up frame (north-west-up), as a 4x4 actor matrix.
NED_TO_DISPLAY = np.eye(4)
NED_TO_DISPLAY[:3, :3] = FRD_TO_FLU
PATTERN_UNITS = {"time": "time, s", "figure-8": "figure-8 in flower", "petal": "petal in flower",
                 "flower": "flower in figure", "arc": "arc in figure-8", "laser": "laser"}
#: The pattern colourings that name a category (a petal, a laser), drawn with a legend of distinct colours.
CATEGORICAL_PATTERN_COLOURS = ("figure-8", "petal", "flower", "arc", "laser")
#: The four arcs of a figure-8 in the order they are traced (scan-model.md section 3: upper-left out, lower-left
#: in, upper-right out, lower-right in), short: a legend's marks stand left of its bar, between it and the pattern.
ARC_NAMES = ("1 UL out", "2 LL in", "3 UR out", "4 LR in")
#: Distinct colours of categories (Tableau 20's strong half first, then its light half, its two greys replaced by
#: Tableau 20b's olive and plum: grey is the reference's), cycled past twenty.
CATEGORY_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#637939",
                    "#bcbd22", "#17becf", "#aec7e8", "#ffbb78", "#98df8a", "#ff9896", "#c5b0d5", "#c49c94",
                    "#f7b6d2", "#7b4173", "#dbdb8d", "#9edae5")
#: Colour maps a user may pick for the continuous colourings (time, range, height).
COLOUR_MAPS = ("turbo", "viridis", "plasma", "inferno", "cividis", "gray")
#: Backgrounds a user may pick for the views: (name, bottom colour, top colour or None).
BACKGROUNDS: dict[str, tuple[str, str | None]] = {"dark": ("#10141c", None), "gradient": ("#1a1f29", "#3b4a63"),
                                                  "black": ("#000000", None), "white": ("#ffffff", None)}
#: The reference overlay's look: light grey, translucent, drawn behind our own points. No colouring but the "gray"
#: map has grey; a light blue read as turbo's blues.
REFERENCE_COLOUR = "#e6e6e6"
#: The reference's grey on a white background, where the light one vanished.
REFERENCE_COLOUR_ON_WHITE = "#4d4d4d"
#: A cloud opened from a file (File > Open cloud), drawn in the scene beside the scan's: the reference's grey.
OPENED_CLOUD_COLOUR = REFERENCE_COLOUR
#: The degree grid's marks and the axes' names, and theirs on a white background (where the first is faint).
GRID_MARK_COLOUR, GRID_MARK_COLOUR_ON_WHITE = "#9aa6b8", "#4a5568"
#: The least height between two marked elevation lines of a panorama, pixels (a 12-point mark is about 14 tall).
ELEVATION_MARK_PX = 16.0
#: Pixels at the top of the pattern view that its text's lines take (kept free of the drawing).
TEXT_BAND_PX = 84
#: The least share of the pattern view's width the pattern keeps beside the colour bar's legend.
PATTERN_LEAST_WIDTH = 0.3
#: Pixels between the field of view's edge and an axis's name, and the rows the names take below it and above it
#: (the gap, a 12-point line, a little air).
NAME_GAP_PX = 6
NAME_BELOW_PX = 30
NAME_ABOVE_PX = 28
REFERENCE_DEPTH = -0.5
SCENE_UNITS = {"range": "range, m", "height": "height, m", "time": "time, s",
               "reflectivity": "reflectivity",
               "return/tag": "return / tag"}
#: Marks of the reflectivity bar: the byte of a 10 %, 50 % and white Lambertian target (0-150 is 0-100 %) and the
#: top of the retroreflective bytes (151-255), not a log scale's ticks (1, 4, 16, 63.8, 255), which mean nothing.
REFLECTIVITY_MARKS = {1.0: "1", 15.0: "15  10 %", 75.0: "75  50 %", 150.0: "150  white", 255.0: "255  retro"}


def reflectivity_marks(low: float, high: float) -> dict[float, str]:
    """Marks of the reflectivity bar from ``low`` to ``high`` (bytes, a log scale): its ends, and those of
    :data:`REFLECTIVITY_MARKS` inside it 8 % of the bar or more from both (nearer, their words overlap)."""
    span = math.log(high / low)
    marks = {end: REFLECTIVITY_MARKS.get(end, f"{end:g}") for end in (low, high)}
    marks.update({value: text for value, text in REFLECTIVITY_MARKS.items()
                  if min(math.log(value / low), math.log(high / value)) >= 0.08 * span})
    return dict(sorted(marks.items()))


#: Colours of the return/tag classes (return 0, 1, 2, 3, mixed, noise).
TAG_COLOURS = ("#9aa5b1", "#4fc3f7", "#ffb74d", "#ba68c8", "#ff5252", "#fff176")


def ring_polydata(ring: PointRing) -> pv.PolyData:
    """A PolyData sharing the ring's point and scalar arrays (zero copy), one vertex per live point."""
    poly = pv.PolyData()
    poly.points = ring.positions
    poly.point_data.set_array(ring.scalars, "scalars")
    poly.point_data.active_scalars_name = "scalars"
    update_ring_polydata(poly, ring)
    return poly


def drawn_slots(ring: PointRing, stride: int = 1) -> np.ndarray:
    """``(k,)`` int64 the ring's slots a view draws: every live one, or with ``stride`` k > 1 those that are
    multiples of k (a level of detail: always the same slots, so the thinned cloud does not shimmer as the ring
    turns). A full ring's are its slots in storage order, the same from tick to tick."""
    full = ring.count == ring.capacity
    slots = ring.all_slots() if full else ring.live_slots()
    if stride > 1:
        slots = np.ascontiguousarray(slots[(-ring.tail if not full else 0) % stride :: stride])
    return slots


def update_ring_polydata(poly: pv.PolyData, ring: PointRing, stride: int = 1,
                         cells: tuple[object, np.ndarray] | None = None) -> None:
    """Tell VTK the ring changed: re-point the vertex cells if the live slots moved, mark the arrays modified.

    A full ring draws every slot, in any order, so its cells stay the same
    from tick to tick and VTK does not rebuild its index buffer. ``stride``:
    see :func:`drawn_slots`. ``cells``: ``(key, slots)``, the slots to draw
    instead (a filter's), made again only when ``key`` changes.
    """
    if poly.GetPoints().GetData().GetVoidPointer(0) != _address(ring.positions):
        poly.points = ring.positions
        poly.point_data.set_array(ring.scalars, "scalars")
        poly.point_data.active_scalars_name = "scalars"
    full = ring.count == ring.capacity
    if cells is not None:
        cells_key = ("given", cells[0])
    else:
        cells_key = (id(ring), "full", stride) if full else (id(ring), ring.tail, ring.count, stride)
    if getattr(poly, "_livox_cells_key", None) != cells_key:
        slots = drawn_slots(ring, stride) if cells is None else cells[1]
        poly.SetVerts(pv.CellArray.from_arrays(ring.cell_offsets()[: slots.size + 1], slots))
        poly._livox_cells_key = cells_key
    poly.GetPoints().GetData().Modified()
    poly.GetPoints().Modified()
    poly.GetPointData().GetArray("scalars").Modified()
    poly.Modified()


#: Points of the scene's cloud drawn at most, unless the drawing is "points": software GL takes about 0.45 ms
#: per thousand points (bench_window.py), so a million drawn cost 450 ms a frame, a quarter of a million 180 ms.
SCENE_DRAW_LIMIT = 250_000


def lod_stride(count: int, limit: int) -> int:
    """Every how many points to draw so that at most ``limit`` of ``count`` are drawn."""
    return max(1, -(-count // limit))


def one_mesh(parts: list[pv.PolyData]) -> pv.PolyData:
    """Line meshes as one mesh, their points and line cells joined with numpy.

    What the guides and the FOV wire are made of: one actor instead of a dozen, and no ``merge`` filter
    (merging and adding them one by one took 65 ms of every change of field of view).
    """
    points, offsets, connectivity, start, end = [], [np.zeros(1, dtype=np.int64)], [], 0, 0
    for part in parts:
        if part.n_points == 0:
            continue
        lines = part.GetLines()
        points.append(np.asarray(part.points, dtype=np.float64))
        connectivity.append(pv.convert_array(lines.GetConnectivityArray()).astype(np.int64) + start)
        offsets.append(pv.convert_array(lines.GetOffsetsArray()).astype(np.int64)[1:] + end)
        start += part.n_points
        end += connectivity[-1].size
    mesh = pv.PolyData()
    if points:
        mesh.points = np.vstack(points)
        mesh.lines = pv.CellArray.from_arrays(np.concatenate(offsets), np.concatenate(connectivity))
    return mesh


def time_marks(low: float, high: float, ticks: int = 5) -> dict[float, str]:
    """Marks of a time colour bar from ``low`` to ``high`` seconds: its two ends and round times between them, each
    with as many decimals as their spacing needs, so no two marks read the same (a 0.5 s window at t = 106 s read
    "106" on every tick).

    Parameters
    ----------
    low, high : float
        Seconds.
    ticks : int
        About how many marks.
    """
    if not high > low:
        return {low: f"{low:.3f}"}
    raw = (high - low) / max(ticks - 1, 1)
    magnitude = 10.0 ** math.floor(math.log10(raw))
    step = next(f * magnitude for f in (1, 2, 5, 10) if raw <= f * magnitude)
    decimals = max(0, -math.floor(math.log10(step) + 1e-9))
    # The ends are not round: one more decimal than the ticks, and the ticks as many, so the column reads evenly.
    decimals = max(decimals, max(0, -math.floor(math.log10(high - low) + 1e-9)) + 1)
    marks = {low: f"{low:.{decimals}f}", high: f"{high:.{decimals}f}"}
    first = math.ceil(low / step + 1e-9) * step
    for k in range(int((high - low) / step) + 2):
        value = first + k * step
        # Keep clear of the ends' labels (closer than a third of a step would overlap them).
        if low + step / 3 < value < high - step / 3:
            marks[value] = f"{value:.{decimals}f}"
    return dict(sorted(marks.items()))


def category_table(labels: list[str]) -> pv.LookupTable:
    """A lookup table of distinct colours, one per category (scalars 0 .. n-1), annotated with the categories'
    names: a legend, not a ramp (at most about a dozen names are written; the colours repeat past twenty)."""
    count = len(labels)
    colours = [CATEGORY_COLOURS[k % len(CATEGORY_COLOURS)] for k in range(count)]
    table = pv.LookupTable(cmap=colours if count > 1 else [colours[0], colours[0]], n_values=max(count, 2))
    table.scalar_range = (-0.5, max(count, 2) - 0.5)
    every = max(1, math.ceil(count / 12))
    table.annotations = {float(k): labels[k] for k in range(0, count, every)}
    return table


def pattern_categories(session: Session) -> list[str]:
    """The category names of the session's categorical pattern colouring, in scalar order."""
    mode = session.display.pattern_colour
    config = session.config
    # Numbers under the bar's title ("figure-8 in flower", "laser"): "figure-8 17" ran into the pattern and over
    # the axis name (a first-use trial), the legend's marks standing left of its bar.
    if mode == "laser":
        return [str(k + 1) for k in range(config.lasers)]
    if mode == "arc":
        return list(ARC_NAMES)
    unit, within = PATTERN_COLOURS[mode]
    count = config.unit_points[within] // config.unit_points[unit]
    return [str(k + 1) for k in range(count)]


def display_points(renderer, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where ``renderer`` draws ``points`` (n, 3) of its world, as VTK's display pixels (origin bottom left), and
    which are in front of the camera (within its clipping range).

    Parameters
    ----------
    renderer : vtkRenderer
    points : (n, 3) float

    Returns
    -------
    xy : (n, 2) float64
        Pixels.
    shown : (n,) bool
    """
    camera = renderer.GetActiveCamera()
    projection = pv.array_from_vtkmatrix(camera.GetCompositeProjectionTransformMatrix(
        renderer.GetTiledAspectRatio(), -1.0, 1.0))
    clip = np.asarray(points, dtype=np.float64) @ projection[:, :3].T + projection[:, 3]
    w = clip[:, 3]
    shown = w > 1e-12
    safe = np.where(shown, w, 1.0)
    ndc = clip[:, :3] / safe[:, None]
    shown &= np.abs(ndc[:, 2]) <= 1.0
    width, height = renderer.GetSize()
    x0, y0 = renderer.GetOrigin()
    xy = np.column_stack([x0 + (ndc[:, 0] + 1.0) * (width / 2.0), y0 + (ndc[:, 1] + 1.0) * (height / 2.0)])
    return xy, shown


def nearest_drawn(xy: np.ndarray, shown: np.ndarray, depth: np.ndarray, at: tuple[float, float],
                  tolerance_px: float) -> int | None:
    """The row of ``xy`` (n, 2) pixels drawn nearest to ``at`` and at most ``tolerance_px`` from it, among those
    ``shown``; of rows within a pixel of the nearest, the one nearest the camera (least ``depth``). None: none
    that near."""
    distance = np.hypot(xy[:, 0] - at[0], xy[:, 1] - at[1])
    distance[~shown] = np.inf
    if distance.size == 0 or not distance.min() <= tolerance_px:
        return None
    close = np.flatnonzero(distance <= distance.min() + 1.0)
    return int(close[np.argmin(depth[close])])


def _address(array: np.ndarray) -> int:
    return int(array.__array_interface__["data"][0])


#: The share of the scene view's width the side camera frames the sensor and the cloud in: about where the colour
#: bar's strip begins (:func:`place_colour_bar` puts it 50-55 px in from the right edge).
SCALAR_BAR_LEFT = 0.82
#: Pixels at the top of the scene view its text's three lines take.
SCENE_TEXT_BAND_PX = 52


#: Pixels of a colour bar's frame, whatever the view's width: VTK draws the strip over the left 3/8 of it (9 px)
#: and centres the title over it.
BAR_FRAME_PX = 24
#: Pixels between a colour bar's words and the view's right edge, and between its legend and the pattern.
LEGEND_EDGE_PX = 6
LEGEND_GAP_PX = 8
#: Pixels VTK leaves between the strip and its annotations' words (their leader lines, to the left) and its
#: labels' words (to the right).
ANNOTATION_LEAD_PX = 11
LABEL_LEAD_PX = 4
#: The bar's frame: from this share of the view's height, this share tall.
BAR_BOTTOM, BAR_HEIGHT = 0.2, 0.6


def add_scalar_bar(plotter: pv.Plotter, title: str, mapper) -> object:
    """The vertical colour bar both views show at their right edge (:func:`place_colour_bar` puts it there)."""
    return plotter.add_scalar_bar(
        title, mapper=mapper, vertical=True, position_x=0.86, position_y=BAR_BOTTOM, width=0.05, height=BAR_HEIGHT,
        title_font_size=12, label_font_size=11, color=BAR_TEXT_COLOURS["dark"], n_labels=5, fmt="%.3g",
    )


def text_width_px(words, text: str, dpi: int) -> int:
    """Pixels ``text`` takes across, drawn with the text property ``words`` at ``dpi``."""
    box = [0, 0, 0, 0]
    if not text or not vtkTextRenderer.GetInstance().GetBoundingBox(words, text, box, dpi):
        return 0
    return box[1] - box[0] + 1


def bar_marks(bar) -> tuple[list[str], list[str]]:
    """The words a colour bar shows beside its strip now: its annotations' (left of it) and its labels' (right)."""
    table = bar.GetLookupTable()
    annotations = ([table.GetAnnotation(k) for k in range(table.GetNumberOfAnnotatedValues())]
                   if bar.GetDrawAnnotations() and table is not None else [])
    count = bar.GetNumberOfLabels()
    labels = ([bar.GetLabelFormat() % value for value in np.linspace(*table.GetRange(), count)]
              if count > 0 and table is not None else [])
    return annotations, labels


def place_colour_bar(bar, renderer, titles: tuple[str, ...] = (), left_marks: tuple[str, ...] = (),
                     right_marks: tuple[str, ...] = ()) -> float:
    """Put ``bar`` at the right edge of ``renderer``'s view, every word of it inside the view, and say where its
    legend begins.

    The words are measured as VTK draws them: the title (centred over the frame), the annotations with their
    leader lines left of the strip, the labels right of it. Room is kept for any of ``titles`` and of the
    ``left_marks`` and ``right_marks`` as well as for the words shown now, so that the bar stays put when the
    colouring or its marks change. Placed as a share of the width, the bar's title ran past a narrow view's edge
    ("return / ta") and its marks into the pattern (a first-use trial).

    Returns
    -------
    float
        The legend's left edge, pixels from the view's left.
    """
    width = max(renderer.GetSize()[0], 1)
    window = renderer.GetRenderWindow()
    dpi = window.GetDPI() if window is not None else 72
    annotations, labels = bar_marks(bar)
    title = max(text_width_px(bar.GetTitleTextProperty(), text, dpi) for text in (bar.GetTitle(), *titles))
    left_words = max((text_width_px(bar.GetAnnotationTextProperty(), text, dpi)
                      for text in (*annotations, *left_marks)), default=0)
    right_words = max((text_width_px(bar.GetLabelTextProperty(), text, dpi) for text in (*labels, *right_marks)),
                      default=0)
    strip = math.ceil(bar.GetBarRatio() * BAR_FRAME_PX)
    # Each side's reach from the frame's left edge, pixels.
    reach_right = max(BAR_FRAME_PX / 2 + title / 2, 1 + strip + (LABEL_LEAD_PX + right_words if right_words else 0))
    reach_left = min(BAR_FRAME_PX / 2 - title / 2, -(ANNOTATION_LEAD_PX + left_words) if left_words else 0)
    frame_left = width - LEGEND_EDGE_PX - reach_right
    place = (frame_left / width, BAR_BOTTOM)
    if tuple(bar.GetPosition()) != place or bar.GetWidth() != BAR_FRAME_PX / width:
        bar.SetPosition(*place)
        bar.SetWidth(BAR_FRAME_PX / width)
        bar.SetHeight(BAR_HEIGHT)
    return frame_left + reach_left


#: The colour bars' words and marks by background: light on the dark ones; on white, where they vanished, dark.
BAR_TEXT_COLOURS = {"dark": "#dde3ea", "white": "#2d3440"}


#: The opacity of the patch of background behind a colour bar's words: bare, the scene's "255 retro" and "150"
#: were lost on the grey buildings and the cloud (a first-use trial), as the grid's marks were.
BAR_TEXT_BACKING_OPACITY = 0.75


def colour_bar_text(bar, background: str) -> None:
    """Colour a colour bar's title, labels and annotations for ``background`` (a key of :data:`BACKGROUNDS`), each
    on a patch of that background."""
    rgb = pv.Color(BAR_TEXT_COLOURS["white" if background == "white" else "dark"]).float_rgb
    backing = pv.Color(BACKGROUNDS.get(background, BACKGROUNDS["dark"])[0]).float_rgb
    for words in (bar.GetTitleTextProperty(), bar.GetLabelTextProperty(), bar.GetAnnotationTextProperty()):
        words.SetColor(rgb)
        words.SetBackgroundColor(backing)
        words.SetBackgroundOpacity(BAR_TEXT_BACKING_OPACITY)


class _View:
    """What both views share: the plotter, the session, and their own renderer in the window.

    Parameters
    ----------
    plotter : pyvista.Plotter
        The view's own plotter (a Qt interactor in the window, an off-screen plotter in renders).
    session : Session
    subplot : tuple of int
        Where the view lives in the plotter.
    """

    #: The key of :data:`BACKGROUNDS` shown.
    background_name: str = "dark"

    @property
    def background(self) -> tuple[str, str | None]:
        """The background's bottom colour and its gradient's top one (None: plain)."""
        return BACKGROUNDS[self.background_name]

    def __init__(self, plotter: pv.Plotter, session: Session, subplot: tuple[int, int] = (0, 0)) -> None:
        self.plotter = plotter
        self.session = session
        self.subplot = subplot
        plotter.subplot(*subplot)
        self.renderer = plotter.renderer
        plotter.set_background(self.background[0], top=self.background[1])
        self.point_size = 2.0

    def set_background(self, name: str) -> None:
        """One of :data:`BACKGROUNDS`."""
        bottom, top = BACKGROUNDS[name]
        self.background_name = name
        self.plotter.subplot(*self.subplot)
        self.plotter.set_background(bottom, top=top)
        colour_bar_text(self.scalar_bar, name)

    def set_point_size(self, pixels: float) -> None:
        """The cloud's points, in pixels (1-10)."""
        self.point_size = float(min(max(pixels, 1.0), 10.0))
        self.actor.GetProperty().SetPointSize(self.point_size)

    #: The titles and marks a view's colour bar may show, room kept for all of them (see :func:`place_colour_bar`).
    LEGEND_TITLES: tuple[str, ...] = ()
    LEGEND_LEFT_MARKS: tuple[str, ...] = ()
    LEGEND_RIGHT_MARKS: tuple[str, ...] = ()

    def place_legend(self) -> float:
        """The colour bar at the view's right edge, whole (:func:`place_colour_bar`); its legend's left edge, px."""
        return place_colour_bar(self.scalar_bar, self.renderer, self.LEGEND_TITLES, self.LEGEND_LEFT_MARKS,
                                self.LEGEND_RIGHT_MARKS)


def panorama_stretch(fov) -> float:
    """How much the pattern view stretches elevation against azimuth: 1 for a boresight pattern (true angles,
    circles stay round); for a 360-degree band, enough that the band is half as tall as it is wide (the Mid-360's
    59 x 360 degrees was a strip 50 px tall in a 600 px view)."""
    if fov.plane != "panorama":
        return 1.0
    x0, x1, y0, y1 = fov.bounds
    return max(1.0, (x1 - x0) / max(y1 - y0, 1e-6) / 2.0)


class PatternView(_View):
    """The angular plane in degrees: FOV outline, degree grid, the live pattern (or its density image), the
    reference behind it.

    A 360-degree band is drawn with its elevation stretched (:func:`panorama_stretch`) so that it fills the view's
    width at a readable height; its marks still read true degrees, and :meth:`plane_point` undoes the stretch.
    """

    #: Marks room is kept for beside the strip besides the categories': a time window's ends and round times
    #: between, and the density's counts (wider ones move the bar, and the pattern is fitted again).
    LEGEND_LEFT_MARKS = ("999.99", "10,000")

    def place_legend(self) -> float:
        """The colour bar at the view's right edge, room kept for the titles and marks of the colourings the
        configuration has (the rosette's arcs' names are the widest; a Risley's lasers are numbers)."""
        colourings = pattern_colours(self.session.config)
        titles = (*(PATTERN_UNITS[mode] for mode in colourings), "points/cell")
        marks = (*self.LEGEND_LEFT_MARKS, *(ARC_NAMES if "arc" in colourings else ()))
        return place_colour_bar(self.scalar_bar, self.renderer, titles, marks)

    def set_background(self, name: str) -> None:
        """One of :data:`BACKGROUNDS`; the reference's grey darkens on white."""
        super().set_background(name)
        self.reference_actor.prop.color = REFERENCE_COLOUR_ON_WHITE if name == "white" else REFERENCE_COLOUR
        if self._guides_fov is not None:
            self.draw_guides()  # the marks' backing takes the new background's colour

    def __init__(self, plotter: pv.Plotter, session: Session, subplot: tuple[int, int] = (0, 0)) -> None:
        super().__init__(plotter, session, subplot)
        self._guides: list = []
        self._guide_actors: tuple | None = None
        self._ring = session.pattern_ring
        self.colour_map = "turbo"
        self.poly = ring_polydata(self._ring)
        self.actor = plotter.add_mesh(
            self.poly, scalars="scalars", cmap=self.colour_map, point_size=self.point_size,
            render_points_as_spheres=False, show_scalar_bar=False, name="pattern", reset_camera=False, lighting=False,
        )
        self._reference_ring = session.overlay.ring
        self.reference_poly = ring_polydata(self._reference_ring)
        # Behind our points (farther from the camera), fainter and smaller: the reference never hides ours.
        self.reference_actor = plotter.add_mesh(
            self.reference_poly, color=REFERENCE_COLOUR, opacity=0.45, point_size=1.5, render_points_as_spheres=False,
            name="reference", reset_camera=False, lighting=False, scalars=None,
        )
        self.scalar_bar = add_scalar_bar(plotter, PATTERN_UNITS[session.display.pattern_colour], self.actor.mapper)
        colour_bar_text(self.scalar_bar, self.background_name)
        self._legend_left = self.place_legend()
        self._density_grid = None
        self.density_actor = None
        self._guides_fov = None
        self._colouring: tuple | None = None
        self.stretch = panorama_stretch(session.config.field_of_view)
        self._make_density_image()
        self.draw_guides()
        self._place_actors()
        self.reset_camera()
        session.subscribe(self._on_change)

    def _on_change(self, what: str) -> None:
        # The guides are drawn from the FOV alone: redrawn (and the camera refitted) when it changed.
        if what == "config" and self._guides_fov != self.session.config.field_of_view:
            self.stretch = panorama_stretch(self.session.config.field_of_view)
            self.draw_guides()
            self._place_actors()
            self.reset_camera()

    def _place_actors(self) -> None:
        """Every actor of the plane at the view's stretch; the reference and the density image behind ours."""
        scale = (1.0, self.stretch, 1.0)
        self.actor.scale = scale
        self.reference_actor.scale = scale
        self.reference_actor.position = (0.0, 0.0, REFERENCE_DEPTH)
        if self.density_actor is not None:
            self.density_actor.scale = scale
        for actor in self._guide_actors or ():
            actor.scale = scale

    def plane_point(self, display_xyz: tuple[float, float, float]) -> tuple[float, float]:
        """Angles (degrees) in the pattern's plane of a point in the view's world coordinates (the stretch undone)."""
        return float(display_xyz[0]), float(display_xyz[1]) / self.stretch

    def _make_density_image(self) -> None:
        """The density image of the window's points (shown instead of the points when they outnumber pixels)."""
        grid = self.session.density
        if grid is self._density_grid:
            return
        self._density_grid = grid
        # A texture on one quad: software GL draws it far faster than a cell per pixel.
        image = pv.ImageData(dimensions=(grid.nx, grid.ny, 1))
        image.point_data.set_array(grid.display, "density")
        image.point_data.active_scalars_name = "density"
        self.density_image = image
        x0, x1, y0, y1 = grid.bounds
        quad = pv.Plane(center=((x0 + x1) / 2, (y0 + y1) / 2, -0.01), direction=(0, 0, 1),
                        i_size=grid.nx * grid.cell, j_size=grid.ny * grid.cell, i_resolution=1, j_resolution=1)
        if self.density_actor is not None:
            # Another grid (the field of view changed): the same texture, lookup table and actor, new image and quad.
            self.density_texture.SetInputData(image)
            self.density_actor.mapper.SetInputData(quad)
            return
        self.density_lut = pv.LookupTable(cmap="inferno", n_values=256)
        self.density_lut.scalar_range = (0.0, 1.0)
        colours = np.array(self.density_lut.values)
        colours[0] = (0, 0, 0, 0)  # empty cells see-through: the background, and a reference drawn behind, show
        self.density_lut.values = colours
        texture = pv.Texture()
        texture.SetInputData(image)
        texture.SetLookupTable(self.density_lut)
        texture.SetColorModeToMapScalars()
        # Linear filtering and mipmaps: a one-texel trace must not vanish when the image is shrunk.
        texture.InterpolateOn()
        texture.MipmapOn()
        self.density_texture = texture
        self.plotter.subplot(*self.subplot)
        self.density_actor = self.plotter.add_mesh(quad, texture=texture, name="density", reset_camera=False,
                                                   lighting=False, show_scalar_bar=False)
        self.density_actor.SetVisibility(False)
        self.density_actor.scale = (1.0, getattr(self, "stretch", 1.0), 1.0)

    def density_shown(self) -> bool:
        """Whether the view draws the density image rather than the points."""
        mode = self.session.display.drawing
        if mode != "auto":
            return mode == "density"
        width, height = self.renderer.GetSize()
        return self.session.pattern_ring.count > max(width * height, 1)

    def mark_colour(self) -> str:
        """The grid marks' and axis names' colour on the background shown."""
        return GRID_MARK_COLOUR_ON_WHITE if self.background_name == "white" else GRID_MARK_COLOUR

    def draw_guides(self) -> None:
        """The field of view's outline, a degree grid, cross hairs, and the axis names.

        The boresight plane gets rings of equal angle off the boresight (kept to the field of view's box);
        the panorama plane gets lines of azimuth and elevation, every one of them marked.
        """
        plotter = self.plotter
        plotter.subplot(*self.subplot)
        if "grid-labels" in self._guides:  # pyvista names a label actor after its name, "-labels" added
            plotter.remove_actor("grid-labels-labels", render=False)
        self._guides = []
        fov = self.session.config.field_of_view
        self._guides_fov = fov
        stretch = self.stretch
        self._azimuth_marks = self.azimuth_mark_step()
        self._elevation_marks = self.elevation_mark_every()
        grid_lines, labels, positions = (_panorama_grid(fov, stretch, self._azimuth_marks, self._elevation_marks)
                                         if fov.plane == "panorama"
                                         else _boresight_grid(fov))
        # The grid and the outline are one mesh each, handed to the same two actors on every change.
        grid = one_mesh(grid_lines)
        boundary = fov.boundary()
        outline = pv.lines_from_points(np.column_stack([boundary, np.zeros(len(boundary))]))
        if self._guide_actors is None:
            self._guide_actors = (
                plotter.add_mesh(grid, color="#3a4454", line_width=1, name="grid", reset_camera=False,
                                 lighting=False, pickable=False),
                plotter.add_mesh(outline, color="#f2c14e", line_width=2, name="fov-outline", reset_camera=False,
                                 lighting=False, pickable=False),
            )
        else:
            for actor, mesh in zip(self._guide_actors, (grid, outline), strict=True):
                actor.mapper.SetInputData(mesh)
        #: The grid's marks as drawn (degrees), for tests and the curious.
        self.guide_labels = list(labels)
        if labels:
            # Each mark on a patch of the background: drawn bare, "20°" was lost in a dense pattern's colours.
            plotter.add_point_labels(positions, labels, font_size=12, text_color=self.mark_colour(),
                                     shape="rounded_rect", shape_color=self.background[0], shape_opacity=0.75,
                                     margin=2, show_points=False, name="grid-labels", always_visible=True,
                                     reset_camera=False)
            self._guides.append("grid-labels")
        self.place_axis_names()

    def place_axis_names(self) -> None:
        """The axes' names, clear of what is drawn at the view's scale now (:meth:`reset_camera` calls it).

        The boresight plane's: x's under the drawn field of view, ending at its right edge (beside it, at 1280x720
        it ran into the colour bar's marks), y's above it, each :data:`NAME_GAP_PX` pixels off its edge. Placed
        a share of the field's height away, the HAP's flat band had "x right, deg" drawn over its bottom.
        """
        plotter = self.plotter
        plotter.subplot(*self.subplot)
        fov = self.session.config.field_of_view
        if fov.plane == "panorama":
            x0, x1, y0, y1 = fov.bounds
            low, high = y0 * self.stretch, y1 * self.stretch
            height = high - low
            names = ["azimuth, deg (x right)", "elevation, deg"]
            places = [(-20.0, low - 0.30 * height, 0.0), (-200.0, high + 0.10 * height, 0.0)]
            justified = {}
        else:
            x0, x1, y0, y1 = self._content_bounds()
            _, height = self.renderer.GetSize()
            per_pixel = 2.0 * self.renderer.camera.parallel_scale / max(height, 1)  # degrees
            gap = NAME_GAP_PX * per_pixel
            centre_x = 0.0 if x0 < 0 < x1 else (x0 + x1) / 2
            names = ["x right, deg", "y up, deg"]
            places = [(x1, y0 - gap, 0.0), (centre_x + gap, y1 + gap, 0.0)]
            # x's anchor is its box's top right corner, y's its bottom left.
            justified = {"justification_horizontal": ["right", "left"], "justification_vertical": ["top", "bottom"]}
        for k, name in enumerate(names):
            plotter.add_point_labels([places[k]], [name], font_size=12, text_color=self.mark_colour(), shape=None,
                                     show_points=False, name=f"axis-label-{k}", always_visible=True,
                                     reset_camera=False, **{key: value[k] for key, value in justified.items()})

    def azimuth_mark_step(self) -> int:
        """Degrees between the panorama's azimuth marks: 45, or 90 where the view is too narrow for "-135°" to
        stand clear of its neighbours (a 330-pixel view at 1280x720 ran them into one another)."""
        _, height = self.renderer.GetSize()
        pixels_per_degree = height / (1.02 * self._fitted_height()[0])
        return 45 if 45.0 * pixels_per_degree >= 40.0 else 90

    def elevation_mark_every(self) -> int:
        """Which of the panorama's elevation lines are marked: every one, or every 2nd, 3rd, ... where the band is
        too short in pixels for a mark a line (in an 1100 px window "50°40°30°" ran into one another)."""
        fov = self.session.config.field_of_view
        if fov.plane != "panorama":
            return 1
        low, high = fov.bounds[2:]
        _, height = self.renderer.GetSize()
        pixels_per_degree = height / (1.02 * self._fitted_height()[0])
        pixels_apart = _ring_step((high - low) * 4 / 6) * self.stretch * pixels_per_degree
        return max(1, math.ceil(ELEVATION_MARK_PX / max(pixels_apart, 1e-6)))

    def refit_guides(self) -> None:
        """Draw the guides again when the view's new size changes which azimuth or elevation marks fit."""
        if self.session.config.field_of_view.plane == "panorama" and (
                self.azimuth_mark_step() != self._azimuth_marks
                or self.elevation_mark_every() != self._elevation_marks):
            self.draw_guides()

    def _content_bounds(self) -> tuple[float, float, float, float]:
        """``(x0, x1, y0, y1)`` in the view's coordinates of the field of view and the reference's when one is
        shown (a wide reference, the HAP's band against the Mid-70, ran past the view's edges)."""
        x0, x1, y0, y1 = self.session.config.field_of_view.bounds
        overlay = self.session.overlay
        if overlay.source is not None and overlay.visible and overlay.source.plane == self.session.config.pattern_plane:
            r0, r1, s0, s1 = overlay.source.fov.bounds
            x0, x1, y0, y1 = min(x0, r0), max(x1, r1), min(y0, s0), max(y1, s1)
        return x0, x1, y0 * self.stretch, y1 * self.stretch

    def drawn_bounds(self) -> tuple[float, float, float, float]:
        """``(x0, x1, y0, y1)`` in the view's coordinates of what :meth:`reset_camera` fits: the field of view,
        the reference's when one is shown, and the guides' marks and the axes' names around them."""
        x0, x1, y0, y1 = self._content_bounds()
        if self.session.config.pattern_plane == "panorama":
            height = y1 - y0
            # Elevation marks on the left, azimuth marks and the axis name below, the elevation name above; on the
            # right as much room as on the left: with 4 degrees, "180°" ran into the colour bar's marks ("61.00").
            return x0 - 28.0, x1 + 28.0, y0 - 0.36 * height, y1 + 0.18 * height
        # The names' rows, in pixels, at the scale the view will have: a share of the height was a few pixels for
        # a flat band. The scale follows from fitting the rest and the rows into the view (see _fitted_height).
        width, height = x1 - x0, y1 - y0
        pixels_w, pixels_h = self.renderer.GetSize()
        aspect = max(pixels_w, 1) / max(pixels_h, 1)
        top = min(0.3, TEXT_BAND_PX / max(pixels_h, 1))
        rows = 1.02 * (NAME_BELOW_PX + NAME_ABOVE_PX) / max(pixels_h, 1)
        visible = max(height / max(1.0 - top - rows, 0.05), 1.05 * width / (aspect * self._usable_width()))
        per_pixel = 1.02 * visible / max(pixels_h, 1)  # degrees
        return (x0 - 0.02 * width, x1 + 0.03 * width, y0 - NAME_BELOW_PX * per_pixel,
                y1 + NAME_ABOVE_PX * per_pixel)

    def _usable_width(self) -> float:
        """The share of the view's width left of the colour bar's legend, less a gap (at least
        :data:`PATTERN_LEAST_WIDTH`)."""
        width = max(self.renderer.GetSize()[0], 1)
        return min(max((self._legend_left - LEGEND_GAP_PX) / width, PATTERN_LEAST_WIDTH), 1.0)

    def reset_camera(self) -> None:
        """Look straight at the pattern plane, orthographic, everything drawn (the reference too) in the view, with
        the colour bar's legend on the right and the text's lines at the top kept free."""
        self._legend_left = self.place_legend()
        x0, x1, y0, y1 = self.drawn_bounds()
        width, height = self.renderer.GetSize()
        aspect = max(width, 1) / max(height, 1)
        camera = self.renderer.camera
        camera.enable_parallel_projection()
        visible, usable, top = self._fitted_height()
        centre = ((x0 + x1) / 2 + (0.5 - usable / 2) * visible * aspect, (y0 + y1) / 2 + top / 2 * visible)
        camera.focal_point = (*centre, 0)
        camera.position = (*centre, max(x1 - x0, y1 - y0) * 10)
        camera.up = (0, 1, 0)
        camera.parallel_scale = visible / 2 * 1.02
        self.renderer.ResetCameraClippingRange()
        self.place_axis_names()

    def _fitted_height(self) -> tuple[float, float, float]:
        """``(visible, usable, top)``: the height of the plane :meth:`reset_camera` shows (degrees, before its 2 %
        margin), and the shares of the view's width and height left for it by the colour bar's legend (measured:
        :meth:`place_legend`) and the text's lines at the top (about 80 px)."""
        x0, x1, y0, y1 = self.drawn_bounds()
        width, height = self.renderer.GetSize()
        aspect = max(width, 1) / max(height, 1)
        usable = self._usable_width()
        top = min(0.3, TEXT_BAND_PX / max(height, 1))
        return max((y1 - y0) / (1 - top), (x1 - x0) / (aspect * usable)), usable, top

    def set_colour_map(self, name: str) -> None:
        """The continuous (time) colouring's map, one of :data:`COLOUR_MAPS`."""
        self.colour_map = name
        self._colouring = None

    def _colour(self) -> None:
        """The points' lookup table and the bar's marks for the colouring in use: a legend of categories, or the
        time window's own start and end with round times between."""
        session = self.session
        mode = session.display.pattern_colour
        low, high = session.pattern_scalar_range()
        categorical = mode in CATEGORICAL_PATTERN_COLOURS
        key = (mode, self.colour_map, (low, high) if categorical else None)
        if key != self._colouring:
            self._colouring = key
            if categorical:
                table = category_table(pattern_categories(session))
            else:
                table = pv.LookupTable(cmap=self.colour_map, n_values=256)
            self.actor.mapper.lookup_table = table
            self.scalar_bar.SetLookupTable(table)
        table = self.actor.mapper.lookup_table
        if categorical:
            self.actor.mapper.scalar_range = table.scalar_range
            self.scalar_bar.SetNumberOfLabels(0)
            self.scalar_bar.SetDrawAnnotations(True)
            return
        table.scalar_range = (low, high if high > low else low + 1e-6)
        self.actor.mapper.scalar_range = table.scalar_range
        table.annotations = time_marks(low, high)
        self.scalar_bar.SetNumberOfLabels(0)
        self.scalar_bar.SetDrawAnnotations(True)

    def update(self) -> None:
        """Show the ring's current points and colours."""
        if self._ring is not self.session.pattern_ring:
            self._ring = self.session.pattern_ring
        self._make_density_image()
        density = self.density_shown()
        self.actor.SetVisibility(not density)
        self.density_actor.SetVisibility(density)
        if density:
            display = self.session.density.refresh_display()
            self.density_image.GetPointData().GetArray("density").Modified()
            # Saturate at four times the mean of the occupied cells: the centre's pile-up would
            # otherwise leave everything else dark.
            counts = self.session.density.counts
            occupied = max(int(np.count_nonzero(counts)), 1)
            top = min(float(display.max()), math.log1p(4.0 * float(counts.sum()) / occupied))
            self.density_lut.scalar_range = (0.0, max(top, 1e-6))
            self.density_lut.annotations = count_marks(top)
            self.density_texture.Modified()
            if self.scalar_bar.GetLookupTable() is not self.density_lut:
                self.scalar_bar.SetLookupTable(self.density_lut)
            # The density's colours are log(1 + count): the bar is marked with counts, not those logarithms.
            self.scalar_bar.SetNumberOfLabels(0)
            self.scalar_bar.SetDrawAnnotations(True)
            self._colouring = None  # the points' table goes back to the bar when the points show again
        else:
            self._colour()
        update_ring_polydata(self.poly, self._ring)
        overlay = self.session.overlay
        self._reference_ring = overlay.ring
        update_ring_polydata(self.reference_poly, self._reference_ring)
        self.reference_actor.SetVisibility(overlay.source is not None and overlay.visible)
        self.scalar_bar.SetTitle("points/cell" if density else PATTERN_UNITS[self.session.display.pattern_colour])
        if self.place_legend() != self._legend_left:  # marks wider than the room kept: fit the pattern again
            self.reset_camera()


def count_marks(top: float) -> dict[float, str]:
    """Marks of a colour bar of log(1 + count) from 0 to ``top``: the counts 0, 1, 2, 5, 10, 20, 50, ... it spans
    (1, 10, 100, ... only, when those would be more than seven), each at its log(1 + count)."""
    counts = [0] + [m * 10**k for k in range(9) for m in (1, 2, 5) if math.log1p(m * 10**k) <= top + 1e-9]
    if len(counts) > 7:
        counts = [c for c in counts if c == 0 or str(c).strip("0") == "1"]
    return {math.log1p(c): f"{c:,}" for c in counts}


def _ring_step(radius: float) -> float:
    """Spacing of the degree rings: about five rings across the FOV, at 1-2-5 steps."""
    raw = radius / 4.0
    magnitude = 10 ** math.floor(math.log10(raw))
    for factor in (1, 2, 5, 10):
        if raw <= factor * magnitude:
            return factor * magnitude
    return 10 * magnitude


def _boresight_grid(fov) -> tuple[list[pv.PolyData], list[str], list[tuple[float, float, float]]]:
    """Rings of equal angle off the boresight, kept inside the field of view's box, with their labels."""
    x0, x1, y0, y1 = fov.bounds
    reach = fov.reach_deg
    step = _ring_step(reach)
    margin = 0.04 * max(x1 - x0, y1 - y0)
    lines, labels, positions = [], [], []
    for ring_radius in np.arange(step, reach + 1e-9, step):
        angle = np.linspace(0.0, 2 * math.pi, 361)
        points = np.column_stack([ring_radius * np.cos(angle), ring_radius * np.sin(angle), np.zeros(angle.size)])
        inside = ((points[:, 0] >= x0 - margin) & (points[:, 0] <= x1 + margin)
                  & (points[:, 1] >= y0 - margin) & (points[:, 1] <= y1 + margin))
        for run in _runs(inside):
            if run.size > 1:
                lines.append(pv.lines_from_points(points[run]))
        label_at = (ring_radius * math.cos(math.radians(60)), ring_radius * math.sin(math.radians(60)), 0.0)
        if x0 <= label_at[0] <= x1 and y0 <= label_at[1] <= y1:
            labels.append(f"{ring_radius:g}°")
            positions.append(label_at)
    lines += [pv.Line((x0, 0, 0), (x1, 0, 0)), pv.Line((0, y0, 0), (0, y1, 0))]
    return lines, labels, positions


def _panorama_grid(fov, stretch: float = 1.0, marked_every: int = 45, elevation_every: int = 1
                   ) -> tuple[list[pv.PolyData], list[str], list[tuple[float, float, float]]]:
    """Lines of azimuth every 45 degrees and of elevation every 10 (or 5, 20) across the band, marked (the
    azimuths every ``marked_every`` degrees, below the band; every elevation, left of it) at the view's
    ``stretch`` of elevation (the lines are stretched by their actor; the marks are placed here)."""
    _, _, low, high = fov.bounds
    lines, labels, positions = [], [], []
    height = (high - low) * stretch
    for azimuth in range(-180, 181, 45):
        lines.append(pv.Line((azimuth, low, 0), (azimuth, high, 0)))
        if azimuth % marked_every == 0:
            labels.append(f"{azimuth}°")
            positions.append((azimuth - 6.0, low * stretch - 0.14 * height, 0.0))
    step = _ring_step((high - low) * 4 / 6)  # about six lines across the band: every 10 degrees for the Mid-360
    for index, elevation in enumerate(np.arange(math.ceil(low / step) * step, high + 1e-9, step)):
        lines.append(pv.Line((-180, elevation, 0), (180, elevation, 0)))
        if index % elevation_every == 0:
            labels.append(f"{elevation:g}°")
            positions.append((-206.0, elevation * stretch - 0.03 * height, 0.0))
    return lines, labels, positions


#: The picks' dots, lines and numbers: a pink no colour map has.
PICK_COLOUR = "#ff4fd8"
#: The picks selected in the Picks panel: a larger dot around their own, white as no colouring's points are.
PICK_SELECTED_COLOUR = "#ffffff"


def pick_numbers_actor(numbers: pv.PolyData) -> object:
    """The picks' numbers beside their dots: ``numbers`` holds the picks' points in the display's frame and their
    labels ("numbers"). Every number in front of the camera is drawn, however close two picks are (the placement
    mapper would drop one that overlaps another; the plain labelled mapper drew those behind the camera too,
    mirrored into the view)."""
    # Loaded at the first pick, not with the window (54 ms of its start).
    from vtkmodules.vtkRenderingCore import vtkActor2D
    from vtkmodules.vtkRenderingLabel import vtkLabelPlacementMapper, vtkPointSetToLabelHierarchy

    hierarchy = vtkPointSetToLabelHierarchy()
    hierarchy.SetInputData(numbers)
    hierarchy.SetLabelArrayName("numbers")
    words = hierarchy.GetTextProperty()
    words.SetFontSize(16)
    words.SetBold(True)
    words.SetColor(pv.Color(PICK_COLOUR).float_rgb)
    # Above and right of the point: the dot (12 px) shows three quarters of itself at the box's corner.
    words.SetJustificationToLeft()
    words.SetVerticalJustificationToBottom()
    mapper = vtkLabelPlacementMapper()
    mapper.SetInputConnection(hierarchy.GetOutputPort())
    mapper.PlaceAllLabelsOn()
    # Read over the cloud and the buildings alike, as the colour bars' words are.
    mapper.SetShapeToRect()
    mapper.SetStyleToFilled()
    mapper.SetBackgroundColor(pv.Color(BACKGROUNDS["dark"][0]).float_rgb)
    mapper.SetBackgroundOpacity(BAR_TEXT_BACKING_OPACITY)
    mapper.SetMargin(2)
    actor = vtkActor2D()
    actor.SetMapper(mapper)
    return actor


def _heading(rotation: np.ndarray) -> float:
    """The vehicle's heading, radians: its x axis turned about the NED vertical (0 north, positive to the east)."""
    forward = np.asarray(rotation)[:, 0]
    return math.atan2(forward[1], forward[0])


def _turn_about_up(angle: float) -> np.ndarray:
    """``(3, 3)`` a turn of the display's frame (z up) that a heading change of ``angle`` radians makes (a NED
    heading turns clockwise seen from above: about the display's z by minus the angle)."""
    c, s = math.cos(-angle), math.sin(-angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _runs(mask: np.ndarray) -> list[np.ndarray]:
    """Index runs where ``mask`` holds."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [np.arange(a, b) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def quadrotor_mesh(size: float = 0.5) -> pv.PolyData:
    """A small quadrotor in its body FRD frame (metres): body, four arms, four rotor discs."""
    parts = [pv.Box(bounds=(-0.12 * size, 0.12 * size, -0.08 * size, 0.08 * size, -0.05 * size, 0.05 * size))]
    for angle in (45, 135, 225, 315):
        direction = np.array([math.cos(math.radians(angle)), math.sin(math.radians(angle)), 0.0])
        tip = direction * 0.35 * size
        parts.append(pv.Cylinder(center=tip / 2, direction=direction, radius=0.015 * size, height=0.35 * size))
        rotor = tip + np.array([0.0, 0.0, -0.04 * size])
        parts.append(pv.Disc(center=rotor, inner=0.0, outer=0.14 * size, normal=(0, 0, 1)))
    merged = parts[0]
    for part in parts[1:]:
        merged = merged.merge(part)
    return merged


def fov_wire(fov, length: float = 1.6) -> pv.PolyData:
    """The field of view as a wire in the sensor frame FRD: its outline's rays at ``length`` and spokes.

    A boresight field of view is its outline's rim with eight rays from the apex; a panoramic band is
    its two rims (lowest and highest elevation) joined by eight meridians, with eight rays to the top rim.
    A translucent surface would hide the cloud behind it and push VTK into its slower translucent pass.
    """
    from livox_viz.patterns.planes import directions_from_xy

    if fov.plane == "panorama":
        low, high = fov.elevation_deg
        azimuth = np.linspace(-180.0, 180.0, 145)
        parts = []
        for elevation in (low, high):
            rim = directions_from_xy(np.column_stack([azimuth, np.full(azimuth.size, elevation)]), "panorama")
            parts.append(pv.lines_from_points(rim * length))
        for spoke in np.arange(-180.0, 180.0, 45.0):
            meridian = np.column_stack([np.full(20, spoke), np.linspace(low, high, 20)])
            arc = directions_from_xy(meridian, "panorama") * length
            parts += [pv.lines_from_points(arc), pv.Line((0.0, 0.0, 0.0), arc[-1])]
        return one_mesh(parts)
    boundary = fov.boundary(96)
    rim = directions_from_xy(boundary, "boresight") * length
    parts = [pv.lines_from_points(rim)]
    parts += [pv.Line((0.0, 0.0, 0.0), rim[k]) for k in np.linspace(0, len(rim) - 1, 9)[:-1].astype(int)]
    return one_mesh(parts)


#: The scene view's camera presets (View menu): behind the sensor looking along its boresight, from above, from
#: the front, from the side; "follow" keeps the user's angle and zoom and moves with the vehicle.
CAMERA_PRESETS = ("behind", "top", "front", "side")
#: The scene camera's vertical view angle, degrees.
SCENE_VIEW_ANGLE = 50.0
#: The side camera: how far ahead it frames before there is a cloud (m), the cloud's points it needs to frame
#: them instead, its elevation (radians), the share of the view's half-angle the framed box may fill, and its
#: least distance (m).
SIDE_REACH_M = 30.0
SIDE_FIT_POINTS = 100
SIDE_ELEVATION = math.radians(15.0)
SIDE_MARGIN = 0.85
SIDE_NEAREST_M = 8.0
#: Points of the cloud an orthographic reset frames at most (a sample: the percentiles of a million are the same).
ORTHO_FIT_SAMPLE = 100_000


#: The display frame's axes (x north, y west, z up): their names and colours (x red, y green, z blue, as VTK and
#: RViz draw them), in the scene and in the corner.
AXES_NAMES = ("N", "W", "up")
AXES_COLOURS = ("#e8574f", "#4fc46b", "#4f9bf0")
#: The corner axes: each axis's length and the corner's margin, pixels; how far apart their names stay.
TRIHEDRON_LENGTH_PX = 34
TRIHEDRON_MARGIN_PX = 16
TRIHEDRON_NAMES_APART_PX = 18


class Trihedron:
    """The display frame's axes in the lower left corner of a 3-D view, a fixed size in pixels, turned as the
    camera turns and each named at its tip, as ParaView's orientation axes and CloudCompare's trihedron are.

    The axes drawn at the world's origin, 5 m long, named by VTK at their tips, were one blob of letters from the
    side camera, far off (a first-use trial): there the axes have no names, and these have them, kept
    :data:`TRIHEDRON_NAMES_APART_PX` apart however the camera looks. Two-dimensional actors of the view's own
    renderer, brought up to date before each render: the same in the window and off-screen.

    Parameters
    ----------
    renderer : vtkRenderer
    text_colour : str
        The names' colour (the colour bar's words' on the view's background).
    backing : str
        The colour of the patch behind each name.
    """

    def __init__(self, renderer, text_colour: str, backing: str) -> None:
        self.renderer = renderer
        self._points = vtkPoints()
        self._points.SetNumberOfPoints(4)
        lines = vtkCellArray()
        for k in range(3):
            lines.InsertNextCell(2)
            lines.InsertCellPoint(0)
            lines.InsertCellPoint(k + 1)
        colours = vtkUnsignedCharArray()
        colours.SetNumberOfComponents(3)
        for colour in AXES_COLOURS:
            colours.InsertNextTuple3(*pv.Color(colour).int_rgb)
        self._poly = vtkPolyData()
        self._poly.SetPoints(self._points)
        self._poly.SetLines(lines)
        self._poly.GetCellData().SetScalars(colours)
        mapper = vtkPolyDataMapper2D()
        mapper.SetInputData(self._poly)
        mapper.SetColorModeToDirectScalars()
        mapper.SetScalarModeToUseCellData()
        self.lines = vtkActor2D()
        self.lines.SetMapper(mapper)
        self.lines.GetProperty().SetLineWidth(3)
        self.names = []
        for name in AXES_NAMES:
            actor = vtkTextActor()
            actor.SetInput(name)
            words = actor.GetTextProperty()
            words.SetFontSize(13)
            words.BoldOn()
            words.SetJustificationToCentered()
            words.SetVerticalJustificationToCentered()
            self.names.append(actor)
        self.set_colours(text_colour, backing)
        for actor in (self.lines, *self.names):
            renderer.AddViewProp(actor)
        self._observer = renderer.AddObserver("StartEvent", lambda *_: self.update())
        self.update()

    def set_colours(self, text_colour: str, backing: str) -> None:
        """The names' colour and their patches' (for the view's background)."""
        for actor in self.names:
            words = actor.GetTextProperty()
            words.SetColor(pv.Color(text_colour).float_rgb)
            words.SetBackgroundColor(pv.Color(backing).float_rgb)
            words.SetBackgroundOpacity(BAR_TEXT_BACKING_OPACITY)

    def name_positions(self) -> np.ndarray:
        """Where each axis's name is drawn (its middle), VTK's display pixels of the view: (3, 2)."""
        x0, y0 = self.renderer.GetOrigin()
        return np.array([actor.GetPosition() for actor in self.names]) + np.array([x0, y0])

    def update(self) -> None:
        """Turn the axes as the camera looks now; each name beyond its axis's tip, apart from the others."""
        view = pv.array_from_vtkmatrix(self.renderer.GetActiveCamera().GetViewTransformMatrix())
        screen = view[:2, :3].T  # each axis's direction on the screen: (right, up) per axis, length <= 1
        origin = np.full(2, TRIHEDRON_MARGIN_PX + TRIHEDRON_LENGTH_PX + 8.0)
        tips = origin + TRIHEDRON_LENGTH_PX * screen
        self._points.SetPoint(0, *origin, 0.0)
        for k in range(3):
            self._points.SetPoint(k + 1, *tips[k], 0.0)
        self._points.Modified()
        self._poly.Modified()
        reach = np.linalg.norm(screen, axis=1)
        away = np.where(reach[:, None] > 0.2, screen / np.maximum(reach, 1e-9)[:, None], (-0.7, -0.7))
        names = origin + (TRIHEDRON_LENGTH_PX * reach + 10.0)[:, None] * away
        # An axis seen end on lies over the middle, and two seen along one line of sight over each other: pushed
        # apart until every two names stand clear.
        for _ in range(20):
            moved = False
            for i in range(3):
                for j in range(i + 1, 3):
                    gap = names[j] - names[i]
                    apart = float(np.hypot(*gap))
                    if apart >= TRIHEDRON_NAMES_APART_PX:
                        continue
                    step = gap / apart if apart > 1e-6 else np.array([1.0, 0.0])
                    push = (TRIHEDRON_NAMES_APART_PX - apart) / 2 + 0.5
                    names[i] -= push * step
                    names[j] += push * step
                    moved = True
            if not moved:
                break
        for actor, (x, y) in zip(self.names, names, strict=True):
            actor.SetPosition(float(x), float(y))

    def remove(self) -> None:
        """Take the axes out of the view."""
        self.renderer.RemoveObserver(self._observer)
        for actor in (self.lines, *self.names):
            self.renderer.RemoveViewProp(actor)


class SceneView(_View):
    """The 3D scene (z up on screen), the vehicle, the sensor with its FOV wire, and the decoded cloud.

    Parameters
    ----------
    plotter, session, subplot
        As :class:`_View`.
    """

    background_name = "gradient"
    LEGEND_TITLES = tuple(SCENE_UNITS.values())
    LEGEND_LEFT_MARKS = (*REFLECTIVITY_MARKS.values(), *TAG_CLASSES, "9999.99")
    LEGEND_RIGHT_MARKS = ("-888.8",)

    def __init__(self, plotter: pv.Plotter, session: Session, subplot: tuple[int, int] = (0, 0)) -> None:
        super().__init__(plotter, session, subplot)
        self._scene_shown = None
        self.colour_map = "viridis"
        self._colouring: tuple | None = None
        #: The reflectivity bar's span its marks were made for.
        self._marked_span: tuple[float, float] | None = None
        #: Whether the camera moves with the vehicle (keeping the user's angle and zoom).
        self.follow = session.trajectory is not None
        self.point_size = 2.5
        self.draw_scene()
        self._ring = session.scene_ring
        self.poly = ring_polydata(self._ring)
        self.actor = plotter.add_mesh(
            self.poly, scalars="scalars", cmap=self.colour_map, point_size=self.point_size,
            render_points_as_spheres=False, show_scalar_bar=False, name="cloud", reset_camera=False, lighting=False,
        )
        self.actor.user_matrix = NED_TO_DISPLAY
        self.scalar_bar = add_scalar_bar(plotter, SCENE_UNITS[session.display.scene_colour], self.actor.mapper)
        colour_bar_text(self.scalar_bar, self.background_name)
        self.place_legend()
        self.grid_actor = None
        self.axes_actor = None
        self.trihedron: Trihedron | None = None
        #: The cloud opened from a file (File > Open cloud), drawn beside the scan's; its name and points, or None.
        self.opened_actor = None
        self.opened: tuple[str, int] | None = None
        #: The range and reflectivity bounds of the points drawn (View > Filters), and the last cells it made:
        #: (key, slots, points hidden).
        self.cloud_filter = CloudFilter()
        self._filtered: tuple[tuple, np.ndarray, int] | None = None
        self.draw_vehicle()
        self.reset_camera()
        session.subscribe(self._on_change)

    def _on_change(self, what: str) -> None:
        """Anything the vehicle, the sensor or its cone depend on may have changed: draw them again."""
        if what == "scene":
            self.draw_scene()
            if self.grid_actor is not None:
                self.show_grid(True)
        self.draw_vehicle()
        if what == "scene":
            self.reset_camera()

    def draw_scene(self) -> None:
        """The scene's triangles (again, when the session's scene changed)."""
        if self._scene_shown is self.session.scene:
            return
        self._scene_shown = self.session.scene
        self.plotter.subplot(*self.subplot)
        # Not named "scene": pyvista's remove_actor("scene") also removes every "scene-..." actor, and the next
        # scene took the view's text ("scene-hud") with the old one.
        self.scene_actor = self.plotter.add_mesh(pv.wrap(self.session.scene.mesh), color="#717d90",
                                                 smooth_shading=False, name="triangles", reset_camera=False,
                                                 pickable=False)
        self.scene_actor.user_matrix = NED_TO_DISPLAY

    def show_grid(self, shown: bool) -> None:
        """A ground grid under the scene, 10 m squares (View menu)."""
        self.plotter.subplot(*self.subplot)
        if self.grid_actor is not None:
            self.plotter.remove_actor(self.grid_actor, render=False)
            self.grid_actor = None
        if not shown:
            return
        low, high = np.asarray(self.session.scene.mesh.bounds)
        ground = float(high[2])  # NED: the lowest surface is the largest z
        x0, y0 = np.floor(low[:2] / 10.0) * 10.0 - 10.0
        x1, y1 = np.ceil(high[:2] / 10.0) * 10.0 + 10.0
        lines = [pv.Line((x, y0, ground), (x, y1, ground)) for x in np.arange(x0, x1 + 1e-9, 10.0)]
        lines += [pv.Line((x0, y, ground), (x1, y, ground)) for y in np.arange(y0, y1 + 1e-9, 10.0)]
        self.grid_actor = self.plotter.add_mesh(one_mesh(lines), color="#56627a", line_width=1, name="ground-grid",
                                                reset_camera=False, lighting=False, pickable=False)
        self.grid_actor.user_matrix = NED_TO_DISPLAY

    def show_axes(self, shown: bool) -> None:
        """The world's axes at its origin, 5 m long, in the display's frame (x north, y west, z up), unnamed, and
        named in the corner (:class:`Trihedron`)."""
        self.plotter.subplot(*self.subplot)
        if self.axes_actor is not None:
            self.plotter.remove_actor(self.axes_actor, render=False)
            self.axes_actor = None
        if self.trihedron is not None:
            self.trihedron.remove()
            self.trihedron = None
        if shown:
            x_colour, y_colour, z_colour = AXES_COLOURS
            self.axes_actor = self.plotter.add_axes_at_origin(labels_off=True, line_width=3, x_color=x_colour,
                                                              y_color=y_colour, z_color=z_colour)
            self.axes_actor.SetTotalLength(5.0, 5.0, 5.0)
            self.trihedron = Trihedron(self.renderer, *self._words_colours())

    def _words_colours(self) -> tuple[str, str]:
        """The colour of words drawn over the view (the colour bar's) and of the patch behind them."""
        name = self.background_name
        return BAR_TEXT_COLOURS["white" if name == "white" else "dark"], BACKGROUNDS[name][0]

    def set_background(self, name: str) -> None:
        """One of :data:`BACKGROUNDS`; the corner axes' names follow it."""
        super().set_background(name)
        if self.trihedron is not None:
            self.trihedron.set_colours(*self._words_colours())

    def show_opened_cloud(self, points_ned: np.ndarray | None, name: str = "") -> None:
        """Draw a cloud opened from a file beside the scan's, static, in :data:`OPENED_CLOUD_COLOUR`; None removes
        it.

        Parameters
        ----------
        points_ned : (n, 3) float32, optional
            World NED, metres (a sensor-frame file already placed with the sensor's pose).
        name : str
            The file's name, for the heads-up text.
        """
        self.plotter.subplot(*self.subplot)
        if points_ned is None:
            if self.opened_actor is not None:
                self.plotter.remove_actor(self.opened_actor, render=False)
            self.opened_actor, self.opened = None, None
            return
        cloud = pv.PolyData(np.ascontiguousarray(points_ned, dtype=np.float32))
        if self.opened_actor is not None:  # another file: the same actor, its new points
            self.opened_actor.mapper.SetInputData(cloud)
        else:
            self.opened_actor = self.plotter.add_mesh(
                cloud, color=OPENED_CLOUD_COLOUR, point_size=self.point_size, render_points_as_spheres=False,
                name="opened-cloud", reset_camera=False, lighting=False, pickable=False)
            self.opened_actor.user_matrix = NED_TO_DISPLAY
        self.opened = (name, cloud.n_points)

    def opened_line(self) -> str:
        """The heads-up line naming the opened cloud, or "" with none."""
        if self.opened is None:
            return ""
        name, count = self.opened
        return f"opened cloud {name}: {count:,} points (light grey)"

    def set_point_size(self, pixels: float) -> None:
        super().set_point_size(pixels)
        if self.opened_actor is not None:
            self.opened_actor.GetProperty().SetPointSize(self.point_size)

    def draw_vehicle(self) -> None:
        """The vehicle at its pose, the sensor and a wire cone of the FOV along its boresight.

        The shapes are made once in their own frames (the cone again only when the FOV changes);
        a change of pose only moves them.
        """
        plotter = self.plotter
        plotter.subplot(*self.subplot)
        if "vehicle" not in plotter.actors:
            plotter.add_mesh(quadrotor_mesh(), color="#e8eef5", name="vehicle", reset_camera=False, pickable=False)
            plotter.add_mesh(pv.Sphere(radius=0.06), color="#f2c14e", name="sensor", reset_camera=False,
                             pickable=False)
        fov = self.session.config.field_of_view
        if getattr(self, "_cone_fov", None) != fov:
            self._cone_fov = fov
            if "fov-cone" in plotter.actors:  # the same actor, a new wire: no remove and add
                plotter.actors["fov-cone"].mapper.SetInputData(fov_wire(fov))
            else:
                plotter.add_mesh(fov_wire(fov), color="#f2c14e", line_width=2, name="fov-cone", reset_camera=False,
                                 lighting=False, pickable=False)
        self.place_vehicle()
        self.draw_path()

    def place_vehicle(self) -> None:
        """Move the vehicle, the sensor and the cone to their poses at the current scan time.

        When following (:attr:`follow`), the camera moves by as much as the vehicle moved, keeping the user's angle
        and zoom.
        """
        actors = self.plotter.actors
        vehicle = self.session.vehicle_pose_now
        actors["vehicle"].user_matrix = NED_TO_DISPLAY @ vehicle.matrix
        for name in ("sensor", "fov-cone"):
            actors[name].user_matrix = NED_TO_DISPLAY @ self.session.sensor_pose.matrix
        here = NED_TO_DISPLAY[:3, :3] @ vehicle.origin
        heading = _heading(vehicle.rotation)
        followed = getattr(self, "_followed", None)
        if self.follow and followed is not None:
            # A chase camera: it moves and turns with the vehicle (about the vertical through it), keeping the
            # user's angle and zoom in the vehicle's own frame, so what the sensor sees stays in view.
            was, turned = followed if isinstance(followed, tuple) else (followed, heading)
            if not (np.array_equal(here, was) and heading == turned):
                turn = _turn_about_up(heading - turned)
                camera = self.renderer.camera
                camera.position = tuple(here + turn @ (np.array(camera.position) - was))
                camera.focal_point = tuple(here + turn @ (np.array(camera.focal_point) - was))
                camera.up = tuple(turn @ np.array(camera.up))
                self.renderer.ResetCameraClippingRange()
        self._followed = (here, heading)

    def draw_path(self) -> None:
        """The trajectory's path as a line (once per trajectory); nothing for a vehicle that stays."""
        trajectory = self.session.trajectory
        if trajectory is None or getattr(self, "_path_of", None) is trajectory:
            return
        self._path_of = trajectory
        stride = max(1, trajectory.t.size // 2000)
        path = pv.lines_from_points(np.asarray(trajectory.position[::stride]))
        self.plotter.subplot(*self.subplot)
        actor = self.plotter.add_mesh(path, color="#7fd3ff", line_width=2, name="path", reset_camera=False,
                                      lighting=False, pickable=False)
        actor.user_matrix = NED_TO_DISPLAY

    def reset_camera(self, preset: str = "behind") -> None:
        """Put the camera at one of :data:`CAMERA_PRESETS` around the sensor.

        ``behind``: behind and above the vehicle, looking along the sensor's boresight; ``top``: straight down
        from 60 m, north up; ``front``: in front of the sensor looking back at it; ``side``: from its left.
        """
        if preset not in CAMERA_PRESETS:
            raise ValueError(f"camera preset {preset!r}; allowed: {', '.join(CAMERA_PRESETS)}")
        orthographic = self.projection == "orthographic"  # kept: r and the presets do not undo the user's choice
        sensor = self.session.sensor_pose
        boresight = sensor.rotation @ np.array([1.0, 0.0, 0.0])
        flat = np.array([boresight[0], boresight[1], 0.0])
        flat = flat / np.linalg.norm(flat) if np.linalg.norm(flat) > 1e-6 else np.array([1.0, 0, 0])
        left = np.array([flat[1], -flat[0], 0.0])  # NED: x north, y east; the sensor's left is -y of its heading
        up = (0, 0, 1)
        if preset == "behind":
            eye_ned = sensor.origin - flat * 9.0 + np.array([0, 0, -4.5])
            target_ned = sensor.origin + flat * 25.0 + np.array([0, 0, 1.0])
        elif preset == "top":
            target_ned = sensor.origin + flat * 20.0
            eye_ned = target_ned + np.array([0.0, 0.0, -60.0])
            up = tuple(NED_TO_DISPLAY[:3, :3] @ flat)
        elif preset == "front":
            eye_ned = sensor.origin + flat * 40.0 + np.array([0, 0, -6.0])
            target_ned = sensor.origin
        else:
            eye_ned, target_ned = self._side_camera(sensor.origin, flat, left)
        to_display = NED_TO_DISPLAY[:3, :3]
        camera = self.renderer.camera
        camera.disable_parallel_projection()
        camera.position = tuple(to_display @ eye_ned)
        camera.focal_point = tuple(to_display @ target_ned)
        camera.up = up
        camera.view_angle = SCENE_VIEW_ANGLE
        if orthographic:
            self._fit_orthographic(tuple(to_display @ eye_ned), flat, left)
        self.renderer.ResetCameraClippingRange()
        vehicle = self.session.vehicle_pose_now
        self._followed = (NED_TO_DISPLAY[:3, :3] @ vehicle.origin, _heading(vehicle.rotation))

    @property
    def projection(self) -> str:
        """The scene camera's projection, one of :data:`~livox_viz.widgets.cameras.PROJECTIONS` (the camera's own
        state: a viewpoint or a sidecar that sets it sets this)."""
        return PROJECTIONS[1] if self.renderer.camera.GetParallelProjection() else PROJECTIONS[0]

    def set_projection(self, projection: str) -> None:
        """Perspective or orthographic, keeping what is looked at the same size on the screen: the parallel scale
        from the eye's distance and the view angle (ParaView keeps the scale it had, and a switch jumped the zoom);
        back to perspective, the eye moved along the line of sight to the distance that scale stands for."""
        if projection not in PROJECTIONS:
            raise LivoxVizError(f"projection {projection!r}; allowed: {', '.join(PROJECTIONS)}")
        if projection == self.projection:
            return
        camera = self.renderer.camera
        if projection == "orthographic":
            camera.parallel_scale = parallel_scale_for(camera.distance, camera.view_angle)
            camera.enable_parallel_projection()
        else:
            distance = distance_for(camera.parallel_scale, camera.view_angle)
            camera.position = tuple(np.asarray(camera.focal_point) - np.asarray(camera.direction) * distance)
            camera.disable_parallel_projection()
        self.renderer.ResetCameraClippingRange()

    def _fit_orthographic(self, eye: tuple[float, float, float], flat: np.ndarray, left: np.ndarray) -> None:
        """Make the camera, looking as a preset put it (its ``eye``, display frame), orthographic and fit the
        sensor and the cloud drawn (its 2nd to 98th percentiles across the screen: stray far points left out) into the
        part of the view the colour bar and the text leave free; before a cloud, the box ahead of the sensor that
        the side camera frames. A perspective preset's fixed distance cut a wide cloud off, or drew it small."""
        camera = self.renderer.camera
        to_display = NED_TO_DISPLAY[:3, :3]
        right, screen_up, forward = screen_axes(np.asarray(camera.direction), np.asarray(camera.up))
        origin = self.session.sensor_pose.origin
        ring = self.session.scene_ring
        # What is drawn: the filter's points when one is on (a range filter's 20 m were a speck in the whole map).
        slots = self._filtered_cells(self.stride())[1] if self.cloud_filter.active else ring.live_slots()
        if slots.size >= SIDE_FIT_POINTS:
            slots = slots[:: max(1, slots.size // ORTHO_FIT_SAMPLE)]
            cloud = ring.positions[slots].astype(np.float64) @ to_display.T
            across = np.stack([cloud @ right, cloud @ screen_up, cloud @ forward], axis=1)
            low, high = np.percentile(across, [2.0, 98.0], axis=0)
            box = np.array([[a, b, c] for a in (low[0], high[0]) for b in (low[1], high[1])
                            for c in (low[2], high[2])]) @ np.stack([right, screen_up, forward])
        else:
            axes = np.stack([flat, left, np.array([0.0, 0.0, -1.0])])  # ahead, left, up (NED)
            box = np.array([[a, b, c] for a in (-2.0, SIDE_REACH_M) for b in (-3.0, 3.0) for c in (-2.0, 3.0)])
            box = (origin + box @ axes) @ to_display.T
        points = np.vstack([box, to_display @ origin])
        width, height = self.renderer.GetSize()
        free_y = 1.0 - min(0.3, SCENE_TEXT_BAND_PX / max(height, 1))
        focal, scale = fit_parallel(points, forward, screen_up, max(width, 1) / max(height, 1), SCALAR_BAR_LEFT,
                                    free_y, SIDE_MARGIN)
        # The eye where the preset had it along the line of sight, or farther: in front of everything framed.
        back = max(float(np.dot(focal - np.asarray(eye), forward)), float(((focal - points) @ forward).max()) + 1.0)
        camera.enable_parallel_projection()
        camera.focal_point = tuple(focal)
        camera.position = tuple(focal - forward * back)
        camera.parallel_scale = scale

    def _side_camera(self, origin: np.ndarray, flat: np.ndarray, left: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(eye, target)``, NED metres, of the side camera: from the sensor's left and a little above, at the
        middle of the box that holds the sensor and the cloud (its 2nd to 98th percentiles each way, stray far
        points left out), far enough that the whole box is in the view, with a margin, at the view's own shape.

        A fixed eye 40 m off, looking 15 m ahead, left the sensor off the edge of a view narrower than tall.
        """
        up = np.array([0.0, 0.0, -1.0])
        axes = np.stack([flat, left, up])  # rows: ahead, left, up
        ring = self.session.scene_ring
        low, high = np.array([-2.0, -3.0, -2.0]), np.array([SIDE_REACH_M, 3.0, 3.0])  # before any cloud
        if ring.count >= SIDE_FIT_POINTS:
            local = (ring.ordered(ring.positions).astype(np.float64) - origin) @ axes.T
            low, high = np.percentile(local, [2.0, 98.0], axis=0)
        low, high = np.minimum(low, 0.0) - 1.0, np.maximum(high, 0.0) + 1.0  # the sensor in the box too
        centre = origin + ((low + high) / 2) @ axes
        corners = np.array([[a, b, c] for a in (low[0], high[0]) for b in (low[1], high[1])
                            for c in (low[2], high[2])]) @ axes + origin - centre
        back = left * math.cos(SIDE_ELEVATION) + up * math.sin(SIDE_ELEVATION)  # from the target to the eye
        view = -back
        right = np.cross(view, up)
        right /= np.linalg.norm(right)
        screen_up = np.cross(right, view)
        # The box goes into the part of the view the colour bar (right) and the text (top) leave free.
        width, height = self.renderer.GetSize()
        free_x, free_y = SCALAR_BAR_LEFT, 1.0 - min(0.3, SCENE_TEXT_BAND_PX / max(height, 1))
        tan_v = math.tan(math.radians(SCENE_VIEW_ANGLE / 2))
        tan_h = tan_v * max(width, 1) / max(height, 1)
        depth = corners @ view
        distance = max(np.max(np.abs(corners @ right) / (tan_h * free_x * SIDE_MARGIN) - depth),
                       np.max(np.abs(corners @ screen_up) / (tan_v * free_y * SIDE_MARGIN) - depth), SIDE_NEAREST_M)
        # Moved right and up, the camera draws the box's middle in the middle of the free part.
        shift = right * (1.0 - free_x) * tan_h * distance + screen_up * (1.0 - free_y) * tan_v * distance
        return centre + back * distance + shift, centre + shift

    def drawn_point_at(self, x_px: float, y_px: float, tolerance_px: float) -> int | None:
        """The ring's slot of the cloud's point drawn nearest to the display position ``(x_px, y_px)`` (VTK's
        pixels, origin bottom left), at most ``tolerance_px`` from it; None when no drawn point is that near.

        Only the points the vertex cells draw (what the time window and the level of detail left), measured on
        the screen: VTK's point picker took its tolerance as a length at the focal plane, and a click on empty sky
        picked a point near the camera 230 pixels away (a first-use trial).
        """
        slots = pv.convert_array(self.poly.GetVerts().GetConnectivityArray())
        if slots is None or slots.size == 0:
            return None
        matrix = np.asarray(self.actor.user_matrix)
        placed = self.poly.points[slots].astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
        xy, shown = display_points(self.renderer, placed)
        depth = np.linalg.norm(placed - self.renderer.GetActiveCamera().GetPosition(), axis=1)
        row = nearest_drawn(xy, shown, depth, (x_px, y_px), tolerance_px)
        return None if row is None else int(slots[row])

    def opened_point_at(self, x_px: float, y_px: float, tolerance_px: float) -> tuple[int, float] | None:
        """The opened cloud's point (File > Open cloud) drawn nearest to the display position ``(x_px, y_px)``, at
        most ``tolerance_px`` from it, as :meth:`drawn_point_at` finds the scan's: its row in the file's points
        and its distance from the position on the screen, pixels; None with no opened cloud or none that near."""
        if self.opened_actor is None:
            return None
        points = np.asarray(self.opened_actor.mapper.GetInput().points, dtype=np.float64)
        placed = points @ NED_TO_DISPLAY[:3, :3].T + NED_TO_DISPLAY[:3, 3]
        xy, shown = display_points(self.renderer, placed)
        depth = np.linalg.norm(placed - self.renderer.GetActiveCamera().GetPosition(), axis=1)
        row = nearest_drawn(xy, shown, depth, (x_px, y_px), tolerance_px)
        if row is None:
            return None
        return row, float(np.hypot(xy[row, 0] - x_px, xy[row, 1] - y_px))

    def screen_distance_px(self, slot: int, x_px: float, y_px: float) -> float:
        """How far the scan's point in ``slot`` of the ring is drawn from the display position, pixels."""
        matrix = np.asarray(self.actor.user_matrix)
        placed = self.poly.points[slot].astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
        xy, _ = display_points(self.renderer, placed[None, :])
        return float(np.hypot(xy[0, 0] - x_px, xy[0, 1] - y_px))

    def opened_point(self, row: int) -> np.ndarray:
        """``(3,)`` float64: the opened cloud's point ``row``, world NED, metres."""
        assert self.opened_actor is not None
        return np.asarray(self.opened_actor.mapper.GetInput().points[row], dtype=np.float64)

    def mark_picks(self, points_ned: list) -> None:
        """Mark the points picked (NED, metres): a dot on each with its number beside it (as CloudCompare labels
        its picks), and the lines the measures are taken along: between the last two, and between the last three
        (their angle at the middle one)."""
        self.plotter.subplot(*self.subplot)
        points = np.asarray(points_ned, dtype=np.float64).reshape(-1, 3)
        if points.shape[0] == 0:
            # pyvista refuses an empty mesh: forgetting the picks before any was made (a seek of the scrubber)
            # said "Empty meshes cannot be plotted" in red. Removing "picks" removes "picks-numbers" too.
            self.plotter.remove_actor("picks", render=False)
            return
        marks = pv.PolyData(points)
        count = points.shape[0]
        measured = min(count, 3)
        if measured >= 2:
            marks.lines = np.array([measured, *range(count - measured, count)])
        numbers = pv.PolyData(points @ NED_TO_DISPLAY[:3, :3].T)
        labels = vtkStringArray()
        labels.SetName("numbers")
        for number in range(1, count + 1):
            labels.InsertNextValue(str(number))
        numbers.GetPointData().AddArray(labels)
        if "picks" in self.plotter.actors:
            self.plotter.actors["picks"].mapper.SetInputData(marks)
            self.plotter.actors["picks-numbers"].GetMapper().GetInputAlgorithm().SetInputData(numbers)
            return
        actor = self.plotter.add_mesh(marks, color=PICK_COLOUR, point_size=12, line_width=3, name="picks",
                                      render_points_as_spheres=True, reset_camera=False, lighting=False,
                                      pickable=False)
        actor.user_matrix = NED_TO_DISPLAY
        self.plotter.add_actor(pick_numbers_actor(numbers), name="picks-numbers", reset_camera=False,
                               pickable=False, render=False)

    def mark_selected_picks(self, points_ned: list) -> None:
        """Ring the picks selected in the Picks panel (NED, metres): a larger white dot behind each one's own
        pink dot, so the row clicked shows where its point is (none: the rings go)."""
        self.plotter.subplot(*self.subplot)
        points = np.asarray(points_ned, dtype=np.float64).reshape(-1, 3)
        if points.shape[0] == 0:
            self.plotter.remove_actor("picks-selected", render=False)
            return
        if "picks-selected" in self.plotter.actors:
            self.plotter.actors["picks-selected"].mapper.SetInputData(pv.PolyData(points))
            return
        actor = self.plotter.add_mesh(pv.PolyData(points), color=PICK_SELECTED_COLOUR, point_size=22,
                                      name="picks-selected", render_points_as_spheres=True, reset_camera=False,
                                      lighting=False, pickable=False)
        actor.user_matrix = NED_TO_DISPLAY

    def turn_about(self, point_ned: np.ndarray) -> None:
        """Make the camera turn about ``point_ned`` (NED, metres) from now on: its focal point goes there, the
        camera moving sideways only (its direction, up and zoom stay), so the point slides to the middle of the
        view and nothing else changes (ParaView's Pick Center, CloudCompare's Pick rotation center).
        :meth:`reset_camera` gives the default centre back."""
        camera = self.renderer.camera
        target = NED_TO_DISPLAY[:3, :3] @ np.asarray(point_ned, dtype=np.float64)
        position = np.asarray(camera.position, dtype=np.float64)
        direction = np.asarray(camera.focal_point, dtype=np.float64) - position
        direction /= np.linalg.norm(direction)
        depth = float(np.dot(target - position, direction))
        if depth <= 1e-3:
            # The point is behind the camera (it turned away since the pick): keep the camera as far from it.
            depth = max(float(np.linalg.norm(target - position)), 1.0)
        camera.position = tuple(target - direction * depth)
        camera.focal_point = tuple(target)
        self.renderer.ResetCameraClippingRange()

    def set_colour_map(self, name: str) -> None:
        """The continuous colourings' map (range, height, time), one of :data:`COLOUR_MAPS`."""
        self.colour_map = name
        self._colouring = None

    def _colour(self) -> None:
        """The lookup table and the bar's marks of the scene colouring in use: categories for return/tag, the
        reflectivity bytes that mean something, a time window's own start and end, numbers for range and height."""
        mode = self.session.display.scene_colour
        low, high = self.session.scene_scalar_range()
        key = (mode, self.colour_map)
        if key != self._colouring:
            self._colouring = key
            self._marked_span = None
            if mode == "return/tag":
                table = pv.LookupTable(cmap=list(TAG_COLOURS), n_values=len(TAG_COLOURS))
                table.annotations = dict(enumerate(TAG_CLASSES))
            else:
                table = pv.LookupTable(cmap="viridis" if mode == "reflectivity" else self.colour_map, n_values=256)
                if mode == "reflectivity":
                    # 1-255 logarithmically: dark asphalt at grazing incidence, paint and walls, signs.
                    table.log_scale = True
            annotated = mode in ("return/tag", "reflectivity", "time")
            self.actor.mapper.lookup_table = table
            self.scalar_bar.SetLookupTable(table)
            self.scalar_bar.SetNumberOfLabels(0 if annotated else 5)
            self.scalar_bar.SetDrawAnnotations(annotated)
            colour_bar_text(self.scalar_bar, self.background_name)
        table = self.actor.mapper.lookup_table
        table.scalar_range = (low, high if high > low else low + 1e-6)
        if mode == "time":
            table.annotations = time_marks(low, high)
        elif mode == "reflectivity" and self._marked_span != (low, high):
            # A range the user fixed: its ends marked, and only the bytes that mean something inside it.
            self._marked_span = (low, high)
            table.annotations = reflectivity_marks(low, high)
        self.actor.mapper.scalar_range = table.scalar_range

    def stride(self) -> int:
        """Every how many of the cloud's points are drawn: all with the "points" drawing, else at most
        :data:`SCENE_DRAW_LIMIT` (the ring's capacity decides, so the stride stays put while the window fills)."""
        if self.session.display.drawing == "points":
            return 1
        return lod_stride(self.session.scene_ring.capacity, SCENE_DRAW_LIMIT)

    def drawn_count(self) -> int:
        """How many of the cloud's points are drawn now (the thinned cloud's, or all)."""
        ring = self.session.scene_ring
        stride = self.stride()
        return ring.count if stride == 1 else len(range(0, ring.count, stride))

    def update(self) -> None:
        """Show the ring's current points and colours, and the vehicle where it is now."""
        if self.session.trajectory is not None:
            self.place_vehicle()
        if self._ring is not self.session.scene_ring:
            self._ring = self.session.scene_ring
        self._colour()
        stride = self.stride()
        update_ring_polydata(self.poly, self._ring, stride,
                             self._filtered_cells(stride) if self.cloud_filter.active else None)
        self.scalar_bar.SetTitle(SCENE_UNITS[self.session.display.scene_colour])
        self.place_legend()

    def _filtered_cells(self, stride: int) -> tuple[tuple, np.ndarray]:
        """``(key, slots)``: the drawn slots the filter lets through, made again only when the ring, the drawing or
        the filter changed (a paused window turned by the mouse costs nothing)."""
        session = self.session
        ring = session.scene_ring
        key = (id(ring), ring.head, ring.count, stride, self.cloud_filter, session.scan_number, session.scan_time)
        if self._filtered is None or self._filtered[0] != key:
            slots, hidden = filtered_slots(ring, drawn_slots(ring, stride), self.cloud_filter)
            self._filtered = (key, slots, hidden)
        return key, self._filtered[1]

    def filter_line(self) -> str:
        """The heads-up line of the filter ("" with none): its bounds and how many of the window's points it
        hides."""
        if not self.cloud_filter.active:
            return ""
        hidden = self._filtered[2] if self._filtered is not None else 0
        return f"filter: {self.cloud_filter.describe()}, {hidden:,} of {self.session.scene_ring.count:,} hidden"
