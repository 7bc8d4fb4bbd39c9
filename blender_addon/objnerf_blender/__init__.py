"""objnerf for Blender: import objnerf runs and scenes, author edits and camera paths, render
them with `objnerf render-edit` and composite the frames with Blender's own objects, and export
a Blender scene as a nerfstudio dataset.

The add-on is thin over the `objnerf` binary (Preferences > Add-ons > objnerf): the heavy work
stays in Rust. Module map: `frames` (every convention), `formats` (files), `cli` (the binary),
`props` (data on objects), `build` (Blender objects), `importer`, `edit`, `camera_path`,
`render`, `dataset` (operators), `ui` (the sidebar panel and File > Import), `compat` (what
differs between Blender 4.5 and 5.x).
"""

import bpy

from . import camera_path, compat, dataset, edit, importer, prefs, props, render, ui

# Registered in this order (property groups first: operators and panels use them).
_MODULES = (prefs, importer, edit, camera_path, render, dataset, ui)


def _classes():
    for m in _MODULES:
        yield from m.CLASSES


def register():
    # An older Blender stops here, with a message naming both versions, before anything is
    # registered (the extension installer already refuses it by the manifest's minimum).
    compat.require_supported()
    props.register()
    for c in _classes():
        bpy.utils.register_class(c)
    ui.register_menus()


def unregister():
    ui.unregister_menus()
    for c in reversed(list(_classes())):
        bpy.utils.unregister_class(c)
    props.unregister()
