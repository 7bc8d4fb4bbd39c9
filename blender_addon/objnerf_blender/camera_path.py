"""The animated camera as nerfstudio's `camera_path.json`, in the capture ("data") frame or, given
the nerfstudio run's `dataparser_transforms.json`, in nerfstudio's viewer frame, which
`ns-render camera-path` reads. The file says which (`"objnerf_frame": "data"` or `"viewer"`; nerfstudio
ignores the key).

Per frame (scene frame_start..frame_end, every frame): `camera_to_world` is the camera's
`matrix_world` taken into the capture frame (root^-1 @ matrix_world) with its scale divided out,
as 16 row-major floats; Blender cameras and nerfstudio's are both OpenGL-style (looking down -z,
y up), so no axis changes. `fov` is the vertical field of view in degrees from the lens, the
sensor size and fit and the image aspect; `aspect` is width / height. The size is the render
resolution times its percentage, `fps` the scene's frame rate.

nerfstudio's camera path has no principal point and square pixels only, so lens shift and
non-square pixel aspect are refused (they would render a different image), not dropped.
The viewer frame is `objnerf camera-path DATA_PATH --dataparser-transforms F --scene S --out OUT
--frame viewer` on the data-frame path, S being the root's scene (for the dataset's
`applied_transform`, which nerfstudio undoes first): the binary owns that conversion.

`read_camera_path` reads a file back the way nerfstudio's `get_path_from_json` does.
"""

import json
import math
import os
import tempfile

import bpy
import numpy as np
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper

from . import cli, frames, prefs, props
from .errors import ObjnerfError, reports_errors

# The key that says which world a camera path's matrices are in (src/scene/camera_path.rs).
FRAME_KEY = "objnerf_frame"


def camera_path_document(context, cam, root):
    """The camera path (a dict) of `cam` over the scene's frame range, in `root`'s capture frame."""
    scene = context.scene
    if cam is None or cam.type != "CAMERA":
        raise ObjnerfError("no camera: set the scene's active camera")
    w, h = frames.render_size(scene)
    r = scene.render
    if abs(r.pixel_aspect_x - r.pixel_aspect_y) > 1e-6:
        raise ObjnerfError("camera_path.json has square pixels only: set the render pixel aspect to 1:1")
    fps = r.fps / r.fps_base
    path, keep = [], scene.frame_current
    try:
        for f in range(scene.frame_start, scene.frame_end + 1):
            scene.frame_set(f)
            data = cam.data
            if abs(data.shift_x) > 1e-9 or abs(data.shift_y) > 1e-9:
                raise ObjnerfError(f"camera '{cam.name}' has a lens shift at frame {f}: camera_path.json has no principal point")
            c2w = frames.rigid_part(root.matrix_world.inverted() @ cam.matrix_world)
            path.append({
                "camera_to_world": [c2w[i][j] for i in range(4) for j in range(4)],
                "fov": frames.vertical_fov_degrees(data, w, h),
                "aspect": w / h,
            })
    finally:
        scene.frame_set(keep)
    return {
        FRAME_KEY: "data",
        "camera_type": "perspective",
        "render_width": w,
        "render_height": h,
        "fps": fps,
        "seconds": len(path) / fps,
        "camera_path": path,
    }


def _write_json(doc, filepath):
    with open(filepath + ".tmp", "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=2)
        f.write("\n")
    os.replace(filepath + ".tmp", filepath)


def write_camera_path(context, cam, root, filepath, dataparser_transforms="", binary=None):
    """Write `cam`'s path to `filepath`: in the capture frame, or with `dataparser_transforms` (a
    nerfstudio run's file) in nerfstudio's viewer frame through `binary` (the objnerf executable).
    Returns the document written. Nothing is written when anything fails."""
    doc = camera_path_document(context, cam, root)
    os.makedirs(os.path.dirname(os.path.abspath(filepath)), exist_ok=True)
    if not dataparser_transforms:
        _write_json(doc, filepath)
        return doc
    if not os.path.isfile(dataparser_transforms):
        raise ObjnerfError(f"{dataparser_transforms}: no such file (the nerfstudio run's dataparser_transforms.json)")
    with tempfile.TemporaryDirectory(prefix="objnerf_path_") as tmp:
        data_path = os.path.join(tmp, "camera_path_data.json")
        _write_json(doc, data_path)
        args = ["camera-path", data_path, "--dataparser-transforms", dataparser_transforms,
                "--out", filepath, "--frame", "viewer"]
        if root.objnerf.scene_path:
            args += ["--scene", root.objnerf.scene_path]
        cli.run(binary, args)
    with open(filepath, encoding="utf-8") as f:
        return json.load(f)


def read_camera_path(filepath):
    """Cameras from a camera_path.json as nerfstudio's `get_path_from_json` builds them:
    [{"c2w": 4x4 array (OpenGL), "fx", "fy", "cx", "cy", "w", "h"}], with
    fx = fy = (h / 2) / tan(fov / 2) and the principal point at the image centre."""
    with open(filepath, encoding="utf-8") as f:
        doc = json.load(f)
    w, h = int(doc["render_width"]), int(doc["render_height"])
    if doc.get("camera_type", "perspective") != "perspective":
        raise ObjnerfError(f"{filepath}: camera_type {doc.get('camera_type')} is not perspective")
    out = []
    for i, c in enumerate(doc["camera_path"]):
        m = np.array(c["camera_to_world"], dtype=np.float64).reshape(4, 4)
        fov = float(c["fov"])
        if not (0 < fov < 180) or not np.all(np.isfinite(m)):
            raise ObjnerfError(f"{filepath}: camera {i} has fov {fov} or a non-finite matrix")
        f = 0.5 * h / math.tan(math.radians(fov) / 2.0)
        out.append({"c2w": m, "fx": f, "fy": f, "cx": w / 2.0, "cy": h / 2.0, "w": w, "h": h})
    return out


class OBJNERF_OT_export_camera_path(bpy.types.Operator, ExportHelper):
    """Write the active camera's animation as nerfstudio's camera_path.json (capture frame, or
    nerfstudio's viewer frame given the run's dataparser_transforms.json)"""

    bl_idname = "objnerf.export_camera_path"
    bl_label = "Export camera_path.json"

    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})
    dataparser_transforms: StringProperty(
        name="dataparser_transforms.json", subtype="FILE_PATH", default="",
        description="The nerfstudio training run's dataparser_transforms.json. Set: the path is "
                    "written in nerfstudio's viewer frame, which ns-render camera-path reads. "
                    "Empty: in the capture (data) frame")

    @reports_errors
    def execute(self, context):
        root = props.active_root(context)
        path = bpy.path.abspath(self.filepath)
        dpt = bpy.path.abspath(self.dataparser_transforms) if self.dataparser_transforms else ""
        binary = prefs.binary(context) if dpt else None
        doc = write_camera_path(context, context.scene.camera, root, path, dpt, binary)
        frame = "nerfstudio's viewer frame" if dpt else "capture frame"
        self.report({"INFO"}, f"wrote {path} ({len(doc['camera_path'])} frames, {frame})")
        return {"FINISHED"}


CLASSES = (OBJNERF_OT_export_camera_path,)
