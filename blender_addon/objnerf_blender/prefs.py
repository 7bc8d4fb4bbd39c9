"""Add-on preferences: where the objnerf binary is (PATH by default) and the models directory."""

import bpy
from bpy.props import StringProperty

from . import cli

# The add-on's module name: "objnerf_blender" as a legacy add-on, "bl_ext.<repo>.objnerf_blender"
# when installed as an extension. Preferences are keyed by it.
ADDON_ID = __package__


class ObjnerfPreferences(bpy.types.AddonPreferences):
    bl_idname = ADDON_ID

    binary: StringProperty(
        name="objnerf binary", subtype="FILE_PATH", default="",
        description="Path to the objnerf executable (empty: 'objnerf' on PATH)")
    models_dir: StringProperty(
        name="Models directory", subtype="DIR_PATH", default="",
        description="objnerf's home for SAM models and caches (OBJNERF_HOME; empty: its default)")

    def draw(self, context):
        col = self.layout.column()
        col.prop(self, "binary")
        col.prop(self, "models_dir")
        try:
            col.label(text=f"Using {cli.find_binary(self.binary)}", icon="CHECKMARK")
        except Exception as e:  # noqa: BLE001 - shown to the user, not raised
            col.label(text=str(e), icon="ERROR")


class _Defaults:
    """Stand-in when the add-on was registered without the add-on system (e.g. from a script)."""

    binary = ""
    models_dir = ""


def get(context=None):
    context = context or bpy.context
    addon = context.preferences.addons.get(ADDON_ID)
    return addon.preferences if addon is not None and addon.preferences is not None else _Defaults()


def binary(context=None):
    """The objnerf executable the preferences point at (ObjnerfError when missing)."""
    return cli.find_binary(get(context).binary)


def models_dir(context=None):
    return bpy.path.abspath(get(context).models_dir) if get(context).models_dir else ""


CLASSES = (ObjnerfPreferences,)
