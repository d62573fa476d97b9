"""curveskel: curve-skeletons (armature + Skin-modifier silhouette) for any mesh.

Importing this package does not import bpy, so ``curveskel_addon.core`` works outside Blender;
the Blender classes are imported in register().
"""

#: The version, in one place for Python: the ``curveskel`` package (pyproject.toml reads it),
#: ``curveskel --version``. blender_manifest.toml repeats it for Blender, which needs it there
#: literally (tests/core/test_packaging.py fails when the two differ).
__version__ = "0.1.0"


def register():
    from . import registration

    registration.register()


def unregister():
    from . import registration

    registration.unregister()
