"""Measures of a curve-skeleton against its mesh (issues 5 and 10): reconstruction distances,
inside fraction, topology, and the shape of the curve (zig-zag, folds, distance to a reference).

Outside the method: the command line's ``--quality``, the benchmark scripts and the tests use
them; the core never imports this package (it has the geometry kernel these measures build on,
:mod:`curveskel_addon.core.geometry`).

Import from the module (``from curveskel_addon.measure.quality import quality``): the package
re-exports nothing, so the function does not hide the module of its name.
"""
