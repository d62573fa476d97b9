"""Add-on preferences: the defaults of a CurveSkel run (Edit > Preferences > Add-ons > CurveSkel)."""

from __future__ import annotations

import bpy

from .properties import ADVANCED_NAMES, OPTION_NAMES, PARAM_NAMES, GenerateSettings

__all__ = ["CURVESKEL_AddonPreferences", "get_preferences", "CLASSES"]


class CURVESKEL_AddonPreferences(GenerateSettings, bpy.types.AddonPreferences):
    """Defaults for new runs: used by the operator when called without a value, and by the
    sidebar's "Reset" button."""

    # The add-on's module name: "curveskel_addon" from a source checkout,
    # "bl_ext.<repo>.curveskel" once installed as an extension.
    bl_idname = __package__

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        col = layout.column(heading="Defaults")
        for name in PARAM_NAMES + ADVANCED_NAMES:
            col.prop(self, name)
        col = layout.column(heading="Create")
        for name in OPTION_NAMES:
            col.prop(self, name)


def get_preferences(context=None):
    """The add-on's preferences, or None when the package was registered without being enabled
    as an add-on (e.g. in tests calling ``register()`` directly)."""
    context = context or bpy.context
    addon = context.preferences.addons.get(__package__)
    return addon.preferences if addon is not None else None


CLASSES = (CURVESKEL_AddonPreferences,)
