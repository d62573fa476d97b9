"""The one place that registers CurveSkel's classes, properties and menu entries.

Register in list order, unregister in reverse; every ``bpy.types.X.prop`` added here is deleted.
"""

from __future__ import annotations

import bpy

from . import ops_bind, ops_evaluate, ops_generate, panel, preferences, properties, results

__all__ = ["CLASSES", "register", "unregister"]

CLASSES = (
    *properties.CLASSES,
    *preferences.CLASSES,
    *ops_generate.CLASSES,
    *ops_bind.CLASSES,
    *panel.CLASSES,
    *ops_evaluate.CLASSES,      # its panel is a child of panel's main one: registered after it
)


def _type_properties():
    """(type, attribute, property) added at registration; built lazily (classes must exist)."""
    return ((bpy.types.Scene, "curveskel",
             bpy.props.PointerProperty(type=properties.CurveSkelSceneSettings,
                                       name="CurveSkel", description="CurveSkel sidebar settings")),
            *results.pointer_properties(),
            *ops_evaluate.type_properties())


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    for owner, attr, prop in _type_properties():
        setattr(owner, attr, prop)
    for menu, entry in panel.MENU_ENTRIES:
        menu.append(entry)


def unregister() -> None:
    for menu, entry in reversed(panel.MENU_ENTRIES):
        menu.remove(entry)
    for owner, attr, _prop in reversed(_type_properties()):
        if hasattr(owner, attr):
            delattr(owner, attr)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
