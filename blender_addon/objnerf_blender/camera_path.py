"""The animated camera as nerfstudio's `camera_path.json`, in the capture ("data") frame.

Per frame (scene frame_start..frame_end, every frame): `camera_to_world` is the camera's
`matrix_world` taken into the capture frame (root^-1 @ matrix_world) with its scale divided out,
as 16 row-major floats; Blender cameras and nerfstudio's are both OpenGL-style (looking down -z,
y up), so no axis changes. `fov` is the vertical field of view in degrees from the lens, the
sensor size and fit and the image aspect; `aspect` is width / height. The size is the render
resolution times its percentage, `fps` the scene's frame rate.

nerfstudio's camera path has no principal point and square pixels only, so lens shift and
non-square pixel aspect are refused (they would render a different image), not dropped.
`read_camera_path` reads a file back the way nerfstudio's `get_path_from_json` does.
"""

import json
import math
import os

import bpy
import numpy as np
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper

from . import frames, props
from .errors import ObjnerfError, reports_errors


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
        "camera_type": "perspective",
        "render_width": w,
        "render_height": h,
        "fps": fps,
        "seconds": len(path) / fps,
        "camera_path": path,
    }


def write_camera_path(context, cam, root, filepath):
    doc = camera_path_document(context, cam, root)
    os.makedirs(os.path.dirname(os.path.abspath(filepath)), exist_ok=True)
    with open(filepath + ".tmp", "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=2)
        f.write("\n")
    os.replace(filepath + ".tmp", filepath)
    return doc


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
    """Write the active camera's animation as nerfstudio's camera_path.json (capture frame)"""

    bl_idname = "objnerf.export_camera_path"
    bl_label = "Export camera_path.json"

    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})

    @reports_errors
    def execute(self, context):
        root = props.active_root(context)
        path = bpy.path.abspath(self.filepath)
        doc = write_camera_path(context, context.scene.camera, root, path)
        self.report({"INFO"}, f"wrote {path} ({len(doc['camera_path'])} frames)")
        return {"FINISHED"}


CLASSES = (OBJNERF_OT_export_camera_path,)
