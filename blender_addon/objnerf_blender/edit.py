"""Authoring edits on proxies and exporting them as the renderer's edit file (docs/edit-format.md).

Moving, turning and scaling a proxy is the edit (Blender's own tools); the operators here add
what Blender has no tool for: duplicate (a second instance of the same model), hide (= the
object removed from the render: `visible: false`), a recolour, and inserting another run's object.

From a proxy's transform in the capture frame, M = root^-1 @ matrix_world = T(loc) R S(s k),
with k = model metres-per-unit / the file's, the edit file's terms are
`translation = loc - k * pivot`, `rotation = R`, `scale = s` (docs/edit-format.md: a point p is
drawn at k * pivot + translation + scale * k * R (p - pivot)).
"""

import json
import os

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty, StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper

from . import build, formats, frames, props
from .errors import ObjnerfError, reports_errors

EDIT_VERSION = 1


def _g7(v):
    """A single-precision Blender value as the short decimal it was typed as (0.1, not 0.100000001)."""
    return float(f"{v:.7g}")


def hex_colour(rgb):
    """'#rrggbb' from sRGB floats 0..1 (Blender's COLOR_GAMMA properties)."""
    return "#" + "".join(f"{max(0, min(255, round(c * 255))):02x}" for c in rgb)


def object_entry(obj, root, file_mpu, edit_dir):
    """One `objects[]` entry of the edit file for a proxy."""
    p = obj.objnerf
    m = root.matrix_world.inverted() @ obj.matrix_world
    if m.to_3x3().determinant() <= 0:
        raise ObjnerfError(f"'{obj.name}' is mirrored or flattened (negative or zero scale): the edit file has a positive uniform scale")
    loc, rot, sc = m.decompose()
    if max(sc) - min(sc) > 1e-4 * max(sc):
        raise ObjnerfError(f"'{obj.name}' has a non-uniform scale {tuple(round(s, 4) for s in sc)}: the edit file has one uniform scale")
    model_mpu = _g7(p.model_metres_per_unit) if p.model_metres_per_unit > 0 else None
    k = (model_mpu / file_mpu) if model_mpu else 1.0
    piv = props.pivot(obj)
    if not p.model:
        raise ObjnerfError(f"proxy '{obj.name}' has no model file")
    entry = {
        "name": obj.name,
        "model": os.path.relpath(bpy.path.abspath(p.model), edit_dir),
        "visible": bool(p.visible),
        "pivot": piv,
        "translation": [loc[i] - k * piv[i] for i in range(3)],
        "rotation": dict(zip("wxyz", frames.quaternion_wxyz(rot))),
        "scale": sum(sc) / 3.0 / k,
    }
    if model_mpu:
        entry["metres_per_unit"] = model_mpu
    if p.recolour_mode == "TARGET":
        entry["recolour"] = {"target": hex_colour(p.recolour_target), "strength": _g7(p.recolour_strength)}
    elif p.recolour_mode == "HUE":
        entry["recolour"] = {"hue_degrees": _g7(p.recolour_hue), "strength": _g7(p.recolour_strength)}
    return entry


def edit_document(context, root, edit_path):
    """The edit file (a dict) for the proxies under `root`; paths relative to `edit_path`'s folder."""
    context.view_layer.update()  # matrix_world of anything moved by a script
    edit_dir = os.path.dirname(os.path.abspath(edit_path))
    r = root.objnerf
    file_mpu = _g7(r.metres_per_unit)
    if r.background_mode == "MODEL":
        if not r.background_model:
            raise ObjnerfError(f"'{root.name}': background is a model but no model file is set")
        background = {"model": os.path.relpath(bpy.path.abspath(r.background_model), edit_dir)}
    else:
        background = {"color": hex_colour(r.background_color)}
    objs = [object_entry(o, root, file_mpu, edit_dir) for o in props.proxies(root)]
    if not objs:
        raise ObjnerfError(f"'{root.name}' has no object proxies to edit")
    return {"version": EDIT_VERSION, "metres_per_unit": file_mpu, "background": background, "objects": objs}


def write_edit(context, root, path):
    doc = edit_document(context, root, path)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path + ".tmp", "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=2)
        f.write("\n")
    os.replace(path + ".tmp", path)
    return doc


# ------------------------------------------------------------------------------- operators


class OBJNERF_OT_duplicate(bpy.types.Operator):
    """Duplicate the selected proxies: another instance of the same object field"""

    bl_idname = "objnerf.duplicate"
    bl_label = "Duplicate object"
    bl_options = {"REGISTER", "UNDO"}

    @reports_errors
    def execute(self, context):
        new = []
        for obj in props.selected_proxies(context):
            dup = obj.copy()  # shares the mesh; copies the objnerf settings and the pivot
            for col in obj.users_collection:
                col.objects.link(dup)
            new.append(dup)
        for o in context.selected_objects:
            o.select_set(False)
        for d in new:
            d.select_set(True)
        context.view_layer.objects.active = new[-1]
        self.report({"INFO"}, "duplicated as " + ", ".join(d.name for d in new))
        return {"FINISHED"}


class OBJNERF_OT_set_visible(bpy.types.Operator):
    """Remove the selected objects from the render (visible: false), or bring them back"""

    bl_idname = "objnerf.set_visible"
    bl_label = "Remove / restore object"
    bl_options = {"REGISTER", "UNDO"}

    visible: BoolProperty(name="Visible", default=False)

    @reports_errors
    def execute(self, context):
        for obj in props.selected_proxies(context):
            obj.objnerf.visible = self.visible
            # Removed objects stay in the viewport as wireframes, so they can be brought back.
            obj.display_type = "TEXTURED" if self.visible else "WIRE"
        return {"FINISHED"}


class OBJNERF_OT_set_recolour(bpy.types.Operator):
    """Set the selected objects' recolour: a target colour or a hue rotation, with a strength"""

    bl_idname = "objnerf.set_recolour"
    bl_label = "Recolour object"
    bl_options = {"REGISTER", "UNDO"}

    mode: EnumProperty(name="Recolour", items=props.RECOLOUR_MODES, default="TARGET")
    target: FloatVectorProperty(name="Target", subtype="COLOR_GAMMA", size=3, min=0.0, max=1.0, default=(0.125, 0.314, 1.0))
    strength: FloatProperty(name="Strength", default=1.0, min=0.0, max=1.0)
    hue_degrees: FloatProperty(name="Hue degrees", default=120.0, min=-360.0, max=360.0)

    @reports_errors
    def execute(self, context):
        for obj in props.selected_proxies(context):
            p = obj.objnerf
            p.recolour_mode, p.recolour_target = self.mode, self.target
            p.recolour_strength, p.recolour_hue = self.strength, self.hue_degrees
        return {"FINISHED"}


class OBJNERF_OT_insert_object(bpy.types.Operator, ImportHelper):
    """Insert an object from another run (its field and mesh) into the active run's scene"""

    bl_idname = "objnerf.insert_object"
    bl_label = "Insert object from run"
    bl_options = {"REGISTER", "UNDO"}

    directory: StringProperty(subtype="DIR_PATH", description="The other run's folder")
    filter_glob: StringProperty(default="report.json", options={"HIDDEN"})
    object_name: StringProperty(name="Object", description="Which object of that run (empty: all of them)")
    model_metres_per_unit: FloatProperty(
        name="Its metres per unit", default=0.0, min=0.0, precision=6,
        description="Unit length of that run's capture in metres (0: the same as this scene's)")
    at_cursor: BoolProperty(name="At the 3D cursor", default=True)

    @reports_errors
    def execute(self, context):
        root = props.active_root(context)
        run_dir = os.path.abspath(bpy.path.abspath(self.directory or os.path.dirname(self.filepath)))
        run = formats.read_run(run_dir)
        objs = [o for o in run["objects"] if not self.object_name or o["name"] == self.object_name]
        if not objs:
            names = ", ".join(o["name"] for o in run["objects"])
            raise ObjnerfError(f"run {run_dir} has no object '{self.object_name}' (it has {names})")
        mpu = self.model_metres_per_unit
        k = mpu / root.objnerf.metres_per_unit if mpu > 0 else 1.0
        cursor = root.matrix_world.inverted() @ context.scene.cursor.location
        col = build.sub_collection(root, "proxies")
        new = []
        for o in objs:
            obj = build.add_proxy(o["name"], o["model"], o["mesh_ply"], root, col, mpu, o["name"])
            obj.scale = (k, k, k)
            if self.at_cursor:
                obj.location = cursor
            else:
                obj.location = [k * v for v in props.pivot(obj)]
            new.append(obj)
        for s in context.selected_objects:
            s.select_set(False)
        for obj in new:
            obj.select_set(True)
        context.view_layer.objects.active = new[-1]
        self.report({"INFO"}, "inserted " + ", ".join(o.name for o in new))
        return {"FINISHED"}


class OBJNERF_OT_export_edit(bpy.types.Operator, ExportHelper):
    """Write the proxies' edits as objnerf's edit file (edit.json, docs/edit-format.md)"""

    bl_idname = "objnerf.export_edit"
    bl_label = "Export edit.json"

    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})

    @reports_errors
    def execute(self, context):
        root = props.active_root(context)
        path = bpy.path.abspath(self.filepath)
        doc = write_edit(context, root, path)
        self.report({"INFO"}, f"wrote {path} ({len(doc['objects'])} objects)")
        return {"FINISHED"}


CLASSES = (OBJNERF_OT_duplicate, OBJNERF_OT_set_visible, OBJNERF_OT_set_recolour,
           OBJNERF_OT_insert_object, OBJNERF_OT_export_edit)
