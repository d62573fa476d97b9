"""curveskel: curve-skeletons (armature + Skin-modifier silhouette) for any mesh.

Importing this package does not import bpy, so ``curveskel_addon.core`` works outside Blender;
the Blender classes are imported in register().
"""


def register():
    from . import registration

    registration.register()


def unregister():
    from . import registration

    registration.unregister()
