"""The VTK/pyvista GUI of livox-viz. It depends on ``livox_viz``; never the reverse."""
