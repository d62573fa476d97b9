"""The rig of a skeleton, as pure maths (NumPy/SciPy, no bpy): bone layout, hierarchy, names and
rolls (:mod:`.rig_layout`), skin weights (:mod:`.skin_weights`), the root joint of each part
(:mod:`.graph_root`).

The Blender layer (``armature.py``, ``binding.py``, ``results.py``) turns these into an armature
and vertex groups. Outside the method: the core never imports this package.

Import from the modules (``from curveskel_addon.rig.rig_layout import rig_layout``): the package
re-exports nothing, so no function hides the module of its name.
"""
