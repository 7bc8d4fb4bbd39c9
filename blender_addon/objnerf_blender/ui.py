"""The "objnerf" tab in the 3D viewport's sidebar (import, edit, camera path, render, dataset)
and the importers' entries in File > Import, where Blender users look for them."""

import bpy

from . import props


class OBJNERF_PT_panel(bpy.types.Panel):
    bl_idname = "OBJNERF_PT_panel"
    bl_label = "objnerf"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "objnerf"

    def draw(self, context):
        layout = self.layout
        col = layout.column(align=True)
        col.label(text="1. Import")
        col.operator("objnerf.import_run", icon="IMPORT")
        col.operator("objnerf.import_scene", icon="CAMERA_DATA")

        obj = context.active_object
        root = props.root_of(obj)
        if root is not None:
            box = layout.box()
            box.label(text=root.name, icon="EMPTY_ARROWS")
            r = root.objnerf
            box.prop(r, "metres_per_unit")
            box.prop(r, "background_mode")
            box.prop(r, "background_color" if r.background_mode == "COLOR" else "background_model")

        col = layout.column(align=True)
        col.label(text="2. Edit (move, rotate, scale the proxies)")
        row = col.row(align=True)
        row.operator("objnerf.duplicate", icon="DUPLICATE")
        row.operator("objnerf.set_visible", text="Remove", icon="HIDE_ON").visible = False
        row.operator("objnerf.set_visible", text="Restore", icon="HIDE_OFF").visible = True
        col.operator("objnerf.set_recolour", icon="COLOR")
        col.operator("objnerf.insert_object", icon="ADD")
        if props.role(obj) == "PROXY":
            p = obj.objnerf
            box = layout.box()
            box.label(text=f"{obj.name}: {'visible' if p.visible else 'removed'}", icon="MESH_DATA")
            box.prop(p, "recolour_mode")
            if p.recolour_mode == "TARGET":
                box.prop(p, "recolour_target")
            elif p.recolour_mode == "HUE":
                box.prop(p, "recolour_hue")
            if p.recolour_mode != "NONE":
                box.prop(p, "recolour_strength")
        col = layout.column(align=True)
        col.operator("objnerf.export_edit", icon="EXPORT")

        col = layout.column(align=True)
        col.label(text="3. Camera path (animate the scene camera)")
        col.operator("objnerf.export_camera_path", icon="CON_CAMERASOLVER")

        col = layout.column(align=True)
        col.label(text="4. Render and composite")
        col.operator("objnerf.render_edit", icon="RENDER_ANIMATION")
        col.operator("objnerf.load_render", icon="IMAGE_BACKGROUND")

        col = layout.column(align=True)
        col.label(text="Blender scene to dataset")
        col.operator("objnerf.export_dataset", icon="OUTLINER_OB_CAMERA")


# (operator, menu text) in File > Import.
IMPORT_MENU = (
    ("objnerf.import_run", "objnerf run (report.json)"),
    ("objnerf.import_scene", "objnerf scene (transforms.json)"),
)


def draw_import_menu(self, context):
    for idname, text in IMPORT_MENU:
        self.layout.operator(idname, text=text)


def register_menus():
    bpy.types.TOPBAR_MT_file_import.append(draw_import_menu)


def unregister_menus():
    bpy.types.TOPBAR_MT_file_import.remove(draw_import_menu)


CLASSES = (OBJNERF_PT_panel,)
