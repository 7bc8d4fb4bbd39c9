"""The add-on's data on Blender objects (`Object.objnerf`) and how objects find their run.

Every object the add-on makes has a role: the ROOT Empty (one per imported run or scene: it
maps the capture frame to Blender's world and holds the edit file's global settings), CAMERAs,
POINTS (point clouds) and PROXYs (an object's mesh standing in for its field; its transform is
the edit). Pivots are kept as double-precision ID properties (`obj["objnerf_pivot"]`): Blender's
float properties are single precision, and the pivot is written to the edit file.
"""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty, StringProperty

from .errors import ObjnerfError

ROLES = [
    ("NONE", "None", "Not made by objnerf"),
    ("ROOT", "Root", "The capture frame of an imported run or scene"),
    ("CAMERA", "Camera", "A capture camera"),
    ("POINTS", "Points", "A point cloud"),
    ("PROXY", "Proxy", "An object's mesh standing in for its radiance field"),
]

PIVOT_KEY = "objnerf_pivot"

RECOLOUR_MODES = [
    ("NONE", "None", "Keep the captured colours"),
    ("TARGET", "Target colour", "Move hue and chroma towards a colour (OKLab, lightness kept)"),
    ("HUE", "Hue rotation", "Rotate the hue in OKLab's a-b plane"),
]


class ObjnerfObjectProps(bpy.types.PropertyGroup):
    role: EnumProperty(items=ROLES, default="NONE")
    # --- ROOT
    run_dir: StringProperty(name="Run", subtype="DIR_PATH", description="The objnerf extract run folder")
    scene_path: StringProperty(name="Scene", subtype="FILE_PATH", description="The capture the run came from")
    metres_per_unit: FloatProperty(
        name="Metres per unit", default=1.0, min=1e-9, precision=6,
        description="Length of one capture unit in metres (edit.json metres_per_unit)")
    background_mode: EnumProperty(
        name="Background",
        items=[("COLOR", "Colour", "A plain colour"), ("MODEL", "Model", "A scene or removal field (.objf)")],
        default="COLOR")
    background_color: FloatVectorProperty(
        name="Background colour", subtype="COLOR_GAMMA", size=3, min=0.0, max=1.0, default=(1.0, 1.0, 1.0))
    background_model: StringProperty(name="Background model", subtype="FILE_PATH")
    # --- PROXY
    model: StringProperty(name="Model", subtype="FILE_PATH", description="The object's field (.objf)")
    source_name: StringProperty(name="Source object", description="The object's name in its run")
    visible: BoolProperty(name="Visible", default=True, description="False: removed from the render")
    model_metres_per_unit: FloatProperty(
        name="Model metres per unit", default=0.0, min=0.0, precision=6,
        description="Unit length of the model's own capture, for objects inserted from another "
                    "capture (0: the same as the scene's)")
    recolour_mode: EnumProperty(name="Recolour", items=RECOLOUR_MODES, default="NONE")
    recolour_target: FloatVectorProperty(
        name="Target", subtype="COLOR_GAMMA", size=3, min=0.0, max=1.0, default=(0.125, 0.314, 1.0))
    recolour_strength: FloatProperty(name="Strength", default=1.0, min=0.0, max=1.0)
    recolour_hue: FloatProperty(name="Hue degrees", default=0.0, min=-360.0, max=360.0)


def role(obj):
    return obj.objnerf.role if obj is not None else "NONE"


def root_of(obj):
    """The ROOT Empty above `obj` (or `obj` itself), else None."""
    while obj is not None:
        if obj.objnerf.role == "ROOT":
            return obj
        obj = obj.parent
    return None


def roots(scene):
    return [o for o in scene.objects if o.objnerf.role == "ROOT"]


def active_root(context):
    """The run the user is working on: the active object's root, else the scene's only root."""
    r = root_of(context.active_object)
    if r is not None:
        return r
    found = roots(context.scene)
    if len(found) == 1:
        return found[0]
    if not found:
        raise ObjnerfError("no objnerf run in this scene: import a run or a scene first")
    raise ObjnerfError("several objnerf runs in this scene: select an object of the one to use")


def proxies(root):
    """The PROXY objects under `root`, in a stable order (by name)."""
    return sorted((o for o in root.children_recursive if o.objnerf.role == "PROXY"), key=lambda o: o.name)


def selected_proxies(context):
    sel = [o for o in context.selected_objects if o.objnerf.role == "PROXY"]
    if not sel:
        raise ObjnerfError("select one or more objnerf proxies (the imported objects' meshes)")
    return sel


def pivot(obj):
    """A proxy's pivot (capture frame, the model's units) as a list of 3 doubles."""
    if PIVOT_KEY not in obj:
        raise ObjnerfError(f"proxy '{obj.name}' has no pivot: import it again")
    return [float(v) for v in obj[PIVOT_KEY]]


CLASSES = (ObjnerfObjectProps,)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Object.objnerf = bpy.props.PointerProperty(type=ObjnerfObjectProps)


def unregister():
    del bpy.types.Object.objnerf
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
