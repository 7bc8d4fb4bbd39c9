"""Import an `objnerf extract` run or a bare scene: cameras, point clouds and object proxies
under one root Empty (see `frames.py` for the frames, `build.py` for the objects).

A run folder gives report.json (the capture-to-glTF frame, the scene it came from, the objects),
`segment/<object>_points.ply` and `<object>/{model.objf, mesh.ply}`. Cameras come from a nerfstudio
transforms.json: the scene's own, or one `objnerf export nerfstudio` writes for other formats
(`cli.transforms_for_scene`).
"""

import os

import bpy
import numpy as np
from bpy.props import BoolProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from . import build, cli, formats, frames, prefs
from .errors import ObjnerfError, reports_errors


def _scene_path(run_dir, scene):
    """report.json's scene path, absolute (relative paths are tried from the run's folder)."""
    if not scene:
        raise ObjnerfError(f"{run_dir}/report.json does not say which scene the run came from")
    if os.path.isabs(scene):
        return scene
    beside = os.path.normpath(os.path.join(run_dir, scene))
    return beside if os.path.exists(beside) else os.path.abspath(scene)


def _extent(tf):
    pos = np.array([np.array(f["c2w"])[:3, 3] for f in tf["frames"]])
    return float(np.max(np.linalg.norm(pos - pos.mean(axis=0), axis=1))) or 1.0


def import_scene(context, scene_path, name=None, capture_to_blender=None, cameras=True, points=True,
                 backgrounds=True):
    """Cameras and sparse points of a scene under a new root; returns (root, collections, tf, notes)."""
    tf_path, exported = cli.transforms_for_scene(scene_path, lambda: prefs.binary(context), prefs.models_dir(context))
    tf = formats.read_transforms(tf_path, undo_applied_transform=exported)
    if capture_to_blender is None:
        capture_to_blender = frames.capture_to_blender_from_cameras([f["c2w"] for f in tf["frames"]])
    if name is None:  # the scene's folder name, also for a transforms.json given as a file
        name = os.path.basename(os.path.dirname(scene_path) if os.path.isfile(scene_path) else os.path.normpath(scene_path))
    root, subs = build.new_root(context, name, capture_to_blender)
    root.objnerf.scene_path = os.path.abspath(scene_path)
    notes = []
    if cameras:
        cams, distorted = build.add_cameras(context, root, subs["cameras"], tf, backgrounds=backgrounds)
        notes.append(f"{len(cams)} cameras")
        if distorted:
            notes.append(f"{distorted} with lens distortion (kept as custom properties, not applied)")
    if points and tf["ply"]:
        if not os.path.isfile(tf["ply"]):
            raise ObjnerfError(f"{tf_path}: ply_file_path {tf['ply']} is missing")
        build.add_points(f"{name} sparse", tf["ply"], root, subs["points"], radius=_extent(tf) * 2e-3,
                         transform=tf["ply_transform"])
        notes.append("sparse points")
    return root, subs, tf, notes


def import_run(context, run_dir, cameras=True, points=True, backgrounds=True):
    """Everything of an extract run; returns (root, notes)."""
    run_dir = os.path.abspath(bpy.path.abspath(run_dir))
    run = formats.read_run(run_dir)
    scene = _scene_path(run_dir, run["scene"])
    c2b = frames.capture_to_blender_from_report(run["report"])
    root, subs, tf, notes = import_scene(
        context, scene, name=os.path.basename(run_dir), capture_to_blender=c2b,
        cameras=cameras, points=points, backgrounds=backgrounds)
    root.objnerf.run_dir = run_dir
    radius = _extent(tf) * 3e-3
    for o in run["objects"]:
        build.add_points(f"{o['name']} points", o["points_ply"], root, subs["points"], radius)
        build.add_proxy(o["name"], o["model"], o["mesh_ply"], root, subs["proxies"])
    notes.append(f"objects {', '.join(o['name'] for o in run['objects'])}")
    return root, notes


def _select_only(context, obj):
    for o in context.selected_objects:
        o.select_set(False)
    if obj.name in context.view_layer.objects:
        obj.select_set(True)
        context.view_layer.objects.active = obj


class OBJNERF_OT_import_run(bpy.types.Operator, ImportHelper):
    """Import an objnerf extract run: cameras, sparse and segmented points, object proxies"""

    bl_idname = "objnerf.import_run"
    bl_label = "Import objnerf run"
    bl_options = {"REGISTER", "UNDO"}

    directory: StringProperty(subtype="DIR_PATH", description="The run folder (objnerf extract --out)")
    filter_glob: StringProperty(default="report.json", options={"HIDDEN"})
    cameras: BoolProperty(name="Cameras", default=True)
    points: BoolProperty(name="Point clouds", default=True)
    backgrounds: BoolProperty(name="Photos as camera backgrounds", default=True)

    @reports_errors
    def execute(self, context):
        run_dir = self.directory or os.path.dirname(self.filepath)
        if not run_dir:
            raise ObjnerfError("choose a run folder")
        root, notes = import_run(context, run_dir, self.cameras, self.points, self.backgrounds)
        _select_only(context, root)
        self.report({"INFO"}, f"imported {root.name}: " + "; ".join(notes))
        return {"FINISHED"}


class OBJNERF_OT_import_scene(bpy.types.Operator, ImportHelper):
    """Import a scene's cameras and sparse points (transforms.json, or any format objnerf reads)"""

    bl_idname = "objnerf.import_scene"
    bl_label = "Import objnerf scene"
    bl_options = {"REGISTER", "UNDO"}

    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})
    backgrounds: BoolProperty(name="Photos as camera backgrounds", default=True)

    @reports_errors
    def execute(self, context):
        path = bpy.path.abspath(self.filepath)
        if not path:
            raise ObjnerfError("choose a scene (transforms.json or a scene folder)")
        root, _subs, _tf, notes = import_scene(context, path, backgrounds=self.backgrounds)
        _select_only(context, root)
        self.report({"INFO"}, f"imported {root.name}: " + "; ".join(notes))
        return {"FINISHED"}


CLASSES = (OBJNERF_OT_import_run, OBJNERF_OT_import_scene)
