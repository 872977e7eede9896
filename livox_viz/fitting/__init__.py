"""Beside the pattern stage: measured scan tables, and fitting and comparing patterns against them.

Takes a scan table (the shipped ``mid40``/``mid70``/``horizon``/``mid360``/``avia``/``tele15``, a ``.npy``,
an ``.npz`` with times or a Livox CSV; rows in any laser order, with gaps, cut anywhere) or a preset replayed
as one, and gives fitted parameters (the rosette's in
:mod:`~livox_viz.fitting.rosette_fit`, the prism track's in
:mod:`~livox_viz.fitting.risley_fit`, any head's track in :mod:`~livox_viz.fitting.track_fit`
through the bounded least squares of :mod:`~livox_viz.fitting.series_lsq`), comparisons of coverage, density and track
(:mod:`~livox_viz.fitting.compare`) and their plot. Nothing in the casting path uses it.
"""
