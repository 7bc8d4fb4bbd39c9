"""A Blender scene as a nerfstudio dataset with exact truth (what BlenderNeRF does, in nerfstudio's
format): `transforms.json`, `images/`, `depth/` (z-depth, 0 = nothing hit) and per-object masks
`masks/<object>/` (8-bit, 255 = the object), plus `objects.json`.

Depth is 16-bit PNG in millimetres by default: what nerfstudio's depth loader reads without flags
(it multiplies by `depth_unit_scale_factor`, 1e-3 by default) and what `objnerf export
nerfstudio` writes. EXR in metres is the option for depth past 65.535 m or below a millimetre;
nerfstudio then needs `--depth-unit-scale-factor 1`. transforms.json says which:
`"depth_unit_scale_factor"` (nerfstudio's name: metres = stored value x factor).

Views come from the selected cameras or a generated ring or dome around the renderable
objects. Each view is rendered twice:

* the image, with the scene's engine settings (Workbench or Cycles, at the requested size);
* a truth pass in Workbench with flat shading, anti-aliasing off and each object painted a
  code colour (`obj.color`), so every pixel holds exactly the object seen at its centre; its
  Z pass, from the same render, is the depth. Both are written by a temporary compositor File
  Output node as float EXR (depth in metres) and decoded here.

Camera matrices are `matrix_world` without scale (OpenGL axes, as nerfstudio's); intrinsics are
computed from lens, sensor size and fit, shift, pixel aspect and resolution as Blender's view plane
is (`frames.camera_intrinsics`, checked against Blender's projection matrix in the tests).
"""

import glob
import json
import math
import os
import re
import shutil
import tempfile

import bpy
import numpy as np
from bpy.props import EnumProperty, FloatProperty, IntProperty, StringProperty
from mathutils import Vector

from . import compat, formats, frames
from .errors import ObjnerfError, reports_errors

RENDERABLE = {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME"}
CODE_BASE = 8  # object code colours: (i + 1) in base 8 over R, G, B, levels k / 7 (511 objects)
NODE_NAME = "objnerf dataset truth"
CAMERA_COLLECTION = "objnerf dataset cameras"
# Metres per stored depth value, per depth format (nerfstudio's depth_unit_scale_factor).
DEPTH_UNIT_SCALE = {"PNG": 1e-3, "EXR": 1.0}
PNG_DEPTH_MAX_MM = 65535


def _hidden_collections(scene):
    hidden, stack = set(), [(scene.collection, False)]
    while stack:
        col, parent_hidden = stack.pop()
        h = parent_hidden or col.hide_render
        if h:
            hidden.add(col.name)
        stack += [(c, h) for c in col.children]
    return hidden


def renderable_objects(context):
    """The objects a render shows, in name order (their code is their index + 1)."""
    hidden = _hidden_collections(context.scene)
    vl = context.view_layer
    return sorted((o for o in context.scene.objects
                   if o.type in RENDERABLE and not o.hide_render and o.visible_get(view_layer=vl)
                   and not all(c.name in hidden for c in o.users_collection)), key=lambda o: o.name)


def code_colour(i):
    """The flat colour of object code i (1-based)."""
    return tuple(((i // CODE_BASE ** c) % CODE_BASE) / (CODE_BASE - 1) for c in range(3)) + (1.0,)


def decode(rgba):
    """Object codes (0 = background) from a truth-pass image (H x W x 4 floats)."""
    d = np.rint(np.clip(rgba[..., :3], 0, 1) * (CODE_BASE - 1)).astype(np.int64)
    code = d[..., 0] + CODE_BASE * d[..., 1] + CODE_BASE * CODE_BASE * d[..., 2]
    return np.where(rgba[..., 3] > 0.5, code, 0)


def safe_name(name):
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)


# -------------------------------------------------------------------------------- cameras


def scene_bounds(objs):
    pts = [o.matrix_world @ Vector(c) for o in objs for c in o.bound_box]
    if not pts:
        raise ObjnerfError("nothing to render: no visible mesh objects in the scene")
    lo = Vector([min(p[i] for p in pts) for i in range(3)])
    hi = Vector([max(p[i] for p in pts) for i in range(3)])
    return (lo + hi) / 2, max((p - (lo + hi) / 2).length for p in pts)


def make_cameras(context, objs, layout, count, lens, elevation_deg, distance):
    """A ring (one elevation) or dome (a spiral over 10..70 degrees) of cameras looking at the
    objects' centre, in their own collection (replacing a previous set)."""
    scene = context.scene
    col = bpy.data.collections.get(CAMERA_COLLECTION)
    if col is None:
        col = bpy.data.collections.new(CAMERA_COLLECTION)
        scene.collection.children.link(col)
    for o in list(col.objects):
        bpy.data.objects.remove(o)
    centre, radius = scene_bounds(objs)
    w, h = frames.render_size(scene)
    if distance <= 0:
        half_fov = math.atan(18.0 / lens * min(w, h) / max(w, h))  # 36 mm sensor, smaller side
        distance = 1.15 * radius / math.sin(half_fov)
    cams = []
    for i in range(count):
        az = 2 * math.pi * i / count
        el = math.radians(elevation_deg) if layout == "RING" else \
            math.radians(10 + 60 * (i + 0.5) / count)
        d = Vector((math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)))
        data = bpy.data.cameras.new(f"view_{i:03d}")
        data.lens = lens
        data.clip_start, data.clip_end = distance * 1e-3, distance * 10
        cam = bpy.data.objects.new(f"view_{i:03d}", data)
        cam.location = centre + distance * d
        cam.rotation_euler = (-d).to_track_quat("-Z", "Y").to_euler()
        col.objects.link(cam)
        cams.append(cam)
    return cams


# -------------------------------------------------------------------------------- rendering


class _Saved:
    """Remembers attributes and puts them back (render settings are the user's)."""

    def __init__(self):
        self.items = []

    def set(self, obj, attr, value):
        self.items.append((obj, attr, getattr(obj, attr)))
        setattr(obj, attr, value)

    def restore(self):
        for obj, attr, value in reversed(self.items):
            setattr(obj, attr, value)


def _truth_nodes(nt, scene, tmp):
    """A File Output node writing the truth pass (RGBA EXR) and the depth (one channel EXR in
    metres, 0 where nothing was hit); returns the nodes, the File Output node second."""
    layers = nt.nodes.new("CompositorNodeRLayers")
    layers.name = NODE_NAME + " layers"
    layers.scene = scene
    out, (id_in, depth_in) = compat.file_output_exr(nt, tmp, [("id_", "RGBA"), ("depth_", "BW")])
    out.name = NODE_NAME
    hit = nt.nodes.new(compat.MATH_NODE)
    hit.name, hit.operation = NODE_NAME + " hit", "LESS_THAN"
    hit.inputs[1].default_value = 1e9  # Blender's Z is 1e10 where nothing was hit
    metres = nt.nodes.new(compat.MATH_NODE)
    metres.name, metres.operation = NODE_NAME + " metres", "MULTIPLY"
    metres.inputs[1].default_value = scene.unit_settings.scale_length
    masked = nt.nodes.new(compat.MATH_NODE)
    masked.name, masked.operation = NODE_NAME + " masked", "MULTIPLY"
    nt.links.new(layers.outputs["Image"], id_in)
    nt.links.new(layers.outputs["Depth"], hit.inputs[0])
    nt.links.new(layers.outputs["Depth"], metres.inputs[0])
    nt.links.new(metres.outputs[0], masked.inputs[0])
    nt.links.new(hit.outputs[0], masked.inputs[1])
    nt.links.new(masked.outputs[0], depth_in)
    return [layers, out, hit, metres, masked]


def _load_exr(path):
    img = bpy.data.images.load(path, check_existing=False)
    img.colorspace_settings.name = "Non-Color"
    w, h = img.size
    a = np.empty(w * h * 4, dtype=np.float32)
    img.pixels.foreach_get(a)
    bpy.data.images.remove(img)
    return a.reshape(h, w, 4)[::-1]  # Blender's rows go bottom-up


def _render_truth(context, tmp, i):
    """Render the truth pass of the current camera; returns (codes H x W, depth EXR path)."""
    for f in glob.glob(os.path.join(tmp, "*.exr")):
        os.remove(f)
    bpy.ops.render.render(write_still=False)
    ids = glob.glob(os.path.join(tmp, "id_*.exr"))
    depth = glob.glob(os.path.join(tmp, "depth_*.exr"))
    if len(ids) != 1 or len(depth) != 1:
        raise ObjnerfError(f"view {i}: the truth pass wrote no EXR files into {tmp}")
    return decode(_load_exr(ids[0])), depth[0]


def export_dataset(context, out_dir, cams, objs, engine, samples, depth_format="PNG", light="STUDIO"):
    """Render every camera into a nerfstudio dataset at `out_dir`; returns the transforms dict.
    `depth_format`: "PNG" (16-bit millimetres) or "EXR" (32-bit float metres)."""
    scene = context.scene
    if depth_format not in DEPTH_UNIT_SCALE:
        raise ObjnerfError(f"depth format must be one of {', '.join(DEPTH_UNIT_SCALE)}, not '{depth_format}'")
    if not cams:
        raise ObjnerfError("no cameras: select cameras or generate a ring or dome")
    if not objs:
        raise ObjnerfError("nothing to render: no visible mesh objects in the scene")
    os.makedirs(out_dir, exist_ok=True)
    for sub in ("images", "depth"):
        os.makedirs(os.path.join(out_dir, sub), exist_ok=True)
    names = {o.name: safe_name(o.name) for o in objs}
    for n in names.values():
        os.makedirs(os.path.join(out_dir, "masks", n), exist_ok=True)
    w, h = frames.render_size(scene)
    pax, pay = scene.render.pixel_aspect_x, scene.render.pixel_aspect_y
    tmp = tempfile.mkdtemp(prefix="objnerf_truth_")
    saved, nodes, nt = _Saved(), [], None
    r = scene.render
    frames_out = []
    try:
        saved.set(scene, "camera", scene.camera)
        saved.set(r, "filepath", r.filepath)
        saved.set(r.image_settings, "file_format", "PNG")
        saved.set(r.image_settings, "color_mode", "RGB")
        saved.set(r.image_settings, "color_depth", "8")
        saved.set(scene.view_layers[0], "use_pass_z", True)
        nt = compat.use_compositor(scene, saved.set)
        for nd in nt.nodes:  # the user's own file outputs stay quiet
            if nd.bl_idname == "CompositorNodeOutputFile":
                saved.set(nd, "mute", True)
        nodes = _truth_nodes(nt, scene, tmp)
        for i, cam in enumerate(cams):
            scene.camera = cam
            stem = f"frame_{i:05d}"
            # 1. The image, as the scene renders.
            image_settings(saved, scene, engine, samples, truth=False, light=light)
            r.filepath = os.path.join(out_dir, "images", stem + ".png")
            nodes[1].mute = True
            bpy.ops.render.render(write_still=True)
            # 2. The truth pass: object codes and depth.
            image_settings(saved, scene, "BLENDER_WORKBENCH", samples, truth=True)
            nodes[1].mute = False
            with _coded(objs):
                codes, depth_exr = _render_truth(context, tmp, i)
            for k, o in enumerate(objs):
                formats.write_png(os.path.join(out_dir, "masks", names[o.name], stem + ".png"),
                                  np.where(codes == k + 1, 255, 0).astype(np.uint8))
            depth_rel = _write_depth(out_dir, stem, depth_exr, depth_format)
            fx, fy, cx, cy = frames.camera_intrinsics(cam.data, w, h, (pax, pay))
            c2w = frames.rigid_part(cam.matrix_world)
            frames_out.append({
                "file_path": f"images/{stem}.png",
                "depth_file_path": depth_rel,
                "transform_matrix": [[c2w[a][b] for b in range(4)] for a in range(4)],
                "fl_x": fx, "fl_y": fy, "cx": cx, "cy": cy,
            })
    finally:
        for nd in nodes:
            nt.nodes.remove(nd)
        saved.restore()
        compat.drop_unused_compositor(nt)
        shutil.rmtree(tmp, ignore_errors=True)
    return _write_transforms(out_dir, frames_out, objs, names, w, h, DEPTH_UNIT_SCALE[depth_format])


def image_settings(saved, scene, engine, samples, truth, light="STUDIO"):
    """Engine settings for the image (engine as chosen; Workbench lit by `light`, textured) or
    the truth pass (flat, no AA)."""
    r = scene.render
    saved.set(r, "engine", engine)
    saved.set(r, "use_compositing", truth)
    saved.set(r, "film_transparent", truth)
    if engine == "CYCLES":
        saved.set(scene.cycles, "samples", samples)
        saved.set(scene.cycles, "device", "CPU")
    sh = scene.display.shading
    if truth:
        saved.set(scene.display, "render_aa", "OFF")
        for attr, value in (("light", "FLAT"), ("color_type", "OBJECT"), ("show_object_outline", False),
                            ("show_cavity", False), ("show_shadows", False), ("show_specular_highlight", False),
                            ("show_xray", False), ("use_dof", False), ("show_backface_culling", False)):
            saved.set(sh, attr, value)
    elif engine == "BLENDER_WORKBENCH":
        saved.set(scene.display, "render_aa", "8")
        for attr, value in (("light", light), ("color_type", "TEXTURE"), ("show_object_outline", False),
                            ("show_cavity", False), ("show_shadows", False), ("show_xray", False)):
            saved.set(sh, attr, value)


class _coded:
    """Objects painted in their code colours for the truth pass, colours restored after."""

    def __init__(self, objs):
        self.objs = objs

    def __enter__(self):
        self.kept = [tuple(o.color) for o in self.objs]
        for k, o in enumerate(self.objs):
            o.color = code_colour(k + 1)

    def __exit__(self, *exc):
        for o, c in zip(self.objs, self.kept):
            o.color = c


def _write_depth(out_dir, stem, depth_exr, depth_format):
    """The view's depth as the dataset stores it; returns its path relative to `out_dir`."""
    if depth_format == "EXR":
        shutil.move(depth_exr, os.path.join(out_dir, "depth", stem + ".exr"))
        return f"depth/{stem}.exr"
    mm = np.rint(_load_exr(depth_exr)[..., 0] / DEPTH_UNIT_SCALE["PNG"])
    # Past 65.535 m a 16-bit millimetre cannot hold it: unknown (0) rather than a wrong depth.
    mm[(mm > PNG_DEPTH_MAX_MM) | ~np.isfinite(mm)] = 0
    formats.write_png(os.path.join(out_dir, "depth", stem + ".png"), mm.astype(np.uint16))
    return f"depth/{stem}.png"


def _write_transforms(out_dir, frames_out, objs, names, w, h, depth_unit_scale):
    """transforms.json in the layout `objnerf export nerfstudio` writes (shared intrinsics at the
    top, per-frame ones where cameras differ; tests/test_dataset.py reads it back through objnerf),
    plus the depth unit; and objects.json."""
    top = {"camera_model": "PINHOLE", "w": w, "h": h}
    keys = ("fl_x", "fl_y", "cx", "cy")
    if all(all(abs(f[k] - frames_out[0][k]) < 1e-9 for k in keys) for f in frames_out):
        top.update({k: frames_out[0][k] for k in keys})
        for f in frames_out:
            for k in keys:
                del f[k]
    tf = {**top, "depth_unit_scale_factor": depth_unit_scale, "frames": frames_out}
    with open(os.path.join(out_dir, "transforms.json"), "w", encoding="utf-8") as f:
        json.dump(tf, f, indent=2)
        f.write("\n")
    with open(os.path.join(out_dir, "objects.json"), "w", encoding="utf-8") as f:
        json.dump({"objects": [{"name": o.name, "code": k + 1, "masks": f"masks/{names[o.name]}"}
                               for k, o in enumerate(objs)]}, f, indent=2)
        f.write("\n")
    return tf


class OBJNERF_OT_export_dataset(bpy.types.Operator):
    """Render the open scene into a nerfstudio dataset: images, depth (16-bit PNG in millimetres,
    or EXR in metres) and per-object masks, from the selected cameras or a generated ring or dome"""

    bl_idname = "objnerf.export_dataset"
    bl_label = "Export scene as dataset"

    directory: StringProperty(name="Folder", subtype="DIR_PATH")
    cameras: EnumProperty(name="Cameras", default="RING", items=[
        ("SELECTED", "Selected", "The selected cameras"),
        ("RING", "Ring", "A ring of cameras at one elevation"),
        ("DOME", "Dome", "A spiral of cameras over the upper hemisphere")])
    count: IntProperty(name="Views", default=24, min=1, max=1000)
    lens: FloatProperty(name="Lens (mm)", default=35.0, min=1.0)
    elevation: FloatProperty(name="Elevation", default=25.0, min=-89.0, max=89.0)
    distance: FloatProperty(name="Distance", default=0.0, min=0.0, description="0: fit the objects")
    engine: EnumProperty(name="Engine", default="BLENDER_WORKBENCH", items=[
        ("BLENDER_WORKBENCH", "Workbench", "Fast, textured, studio light"),
        ("CYCLES", "Cycles", "Path traced on the CPU")])
    samples: IntProperty(name="Cycles samples", default=16, min=1)
    light: EnumProperty(name="Workbench light", default="STUDIO", items=[
        ("STUDIO", "Studio", "Shaded by Workbench's studio light"),
        ("FLAT", "Flat", "Texture colours only, no shading")])
    depth_format: EnumProperty(name="Depth", default="PNG", items=[
        ("PNG", "PNG (mm)", "16-bit millimetres, up to 65.535 m: what nerfstudio reads without flags"),
        ("EXR", "EXR (metres)", "32-bit float metres; nerfstudio needs --depth-unit-scale-factor 1")])

    @reports_errors
    def execute(self, context):
        if not self.directory:
            raise ObjnerfError("choose an output folder")
        objs = renderable_objects(context)
        if self.cameras == "SELECTED":
            cams = sorted((o for o in context.selected_objects if o.type == "CAMERA"), key=lambda o: o.name)
        else:
            cams = make_cameras(context, objs, self.cameras, self.count, self.lens, self.elevation, self.distance)
        out = bpy.path.abspath(self.directory)
        tf = export_dataset(context, out, cams, objs, self.engine, self.samples, self.depth_format, self.light)
        self.report({"INFO"}, f"wrote {len(tf['frames'])} views of {len(objs)} objects to {out}")
        return {"FINISHED"}

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}


CLASSES = (OBJNERF_OT_export_dataset,)
