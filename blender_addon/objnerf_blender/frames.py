"""Frames and camera models: the only place the add-on converts between conventions.

Three frames meet here:

* the **capture frame** (the scene's cameras, sparse points, `.objf` fields, `mesh.ply`, the edit
  file, camera paths): whatever COLMAP or the capture gave, any axis up;
* **glTF** (+Y up), which objnerf's `.glb` meshes use: `report.json`'s `frame.capture_to_gltf`
  (column-major 4x4) takes the capture frame there;
* **Blender's world** (+Z up). Blender's glTF importer turns glTF (x, y, z) into (x, -z, y); that
  is `GLTF_TO_BLENDER` below.

The add-on puts everything it imports under one parent Empty whose matrix is
`GLTF_TO_BLENDER @ capture_to_gltf` (the identity for a +Z-up capture such as the demo scene),
so that every child keeps capture coordinates in its local matrix and exports only have to undo
the parent. The parent only changes what the viewport shows: exports are right whatever it is.

Cameras: nerfstudio/Blender cameras are OpenGL-style (x right, y up, looking down -z), so a
transforms.json `transform_matrix` is directly a Blender camera's local matrix. Intrinsics map
to Blender's camera with a horizontal sensor fit: `lens / sensor_width = fx / w`, and the
principal point becomes the lens shift, which Blender measures in units of the fitted image
dimension (the width here).
"""

import math

from mathutils import Matrix, Quaternion, Vector

# glTF (+Y up) to Blender (+Z up): (x, y, z) -> (x, -z, y), what Blender's glTF importer does.
GLTF_TO_BLENDER = Matrix(((1, 0, 0, 0), (0, 0, -1, 0), (0, 1, 0, 0), (0, 0, 0, 1)))

# Blender's default sensor width (mm); any value works, the focal length is scaled to match.
SENSOR_WIDTH_MM = 36.0


def matrix_from_gltf_cols(cols16):
    """A mathutils Matrix from glTF's column-major 16 floats."""
    if len(cols16) != 16:
        raise ValueError(f"expected 16 numbers for a 4x4 matrix, got {len(cols16)}")
    return Matrix([[cols16[c * 4 + r] for c in range(4)] for r in range(4)])


def capture_to_blender_from_report(report):
    """The parent Empty's matrix for a run, from report.json's `frame.capture_to_gltf`."""
    frame = report.get("frame") or {}
    cols = frame.get("capture_to_gltf")
    if cols is None:
        return None
    return GLTF_TO_BLENDER @ matrix_from_gltf_cols(cols)


def capture_to_blender_from_cameras(c2ws):
    """The parent Empty's matrix for a bare scene (no report.json), chosen as objnerf does for
    meshes: the cameras' mean up vector, snapped to a world axis within 15 degrees, is turned to
    Blender's +Z. `c2ws` are OpenGL camera-to-world matrices (camera up = +y column).

    Display only: exports undo whatever this returns.
    """
    up = Vector((0.0, 0.0, 0.0))
    for m in c2ws:
        up += Vector((m[0][1], m[1][1], m[2][1]))
    if up.length < 1e-9:
        return Matrix.Identity(4)
    up.normalize()
    axes = [Vector(a) for a in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))]
    best = max(axes, key=lambda a: a.dot(up))
    if math.degrees(math.acos(max(-1.0, min(1.0, best.dot(up))))) <= 15.0:
        up = best
    z = Vector((0.0, 0.0, 1.0))
    if up.dot(z) < -1.0 + 1e-12:
        # Upside down: half a turn about x (any horizontal axis would do).
        return Matrix.Rotation(math.pi, 4, "X")
    return up.rotation_difference(z).to_matrix().to_4x4()


def rigid_part(m):
    """`m` (4x4) with its scale divided out of the rotation columns: the camera-to-world that a
    camera path stores. Raises ValueError for a degenerate (zero-scale) matrix."""
    loc, rot, _scale = m.decompose()
    if rot.magnitude < 1e-12:
        raise ValueError("matrix has no rotation (zero scale?)")
    out = rot.normalized().to_matrix().to_4x4()
    out.translation = loc
    return out


# ---------------------------------------------------------------- intrinsics <-> Blender camera


def apply_intrinsics(cam_data, fx, fy, cx, cy, w, h):
    """Set a Blender camera's lens, sensor and shift from pinhole intrinsics (pixels).

    Returns the pixel aspect (x, y) the scene's render settings need for fx != fy: Blender puts
    pixel aspect and resolution on the scene, not on the camera.
    """
    cam_data.type = "PERSP"
    cam_data.sensor_fit = "HORIZONTAL"
    cam_data.sensor_width = SENSOR_WIDTH_MM
    cam_data.lens = fx / w * SENSOR_WIDTH_MM
    # Wider pixels (aspect x > y) mean fewer pixels per unit across: fy / fx = aspect_x / aspect_y.
    if abs(fy - fx) <= 1e-9 * fx:
        aspect = (1.0, 1.0)
    else:
        aspect = (fy / fx, 1.0) if fy > fx else (1.0, fx / fy)
    # Shift is in units of the fitted dimension (the width): positive x moves the image window
    # right, positive y moves it up. A principal point right of centre means the window sits
    # left of the optical axis. Blender's view plane measures y in x's units, so a pixel row is
    # aspect_y / aspect_x of them high.
    ycor = aspect[1] / aspect[0]
    cam_data.shift_x = (0.5 * w - cx) / w
    cam_data.shift_y = (cy - 0.5 * h) * ycor / w
    return aspect


def projection_intrinsics(proj, w, h):
    """Pinhole intrinsics (fx, fy, cx, cy; OpenCV, pixel corner at 0) from a Blender projection
    matrix (`Object.calc_matrix_camera(depsgraph, x=w, y=h, ...)`), which accounts for lens,
    sensor fit, shift and pixel aspect exactly as Blender renders them.

    For camera-frame (x, y, z) looking down -z, NDC x = P00 * x / -z - P02, so u = (NDC x + 1) w / 2
    gives fx = P00 w / 2, cx = (1 - P02) w / 2; likewise (y up) fy = P11 h / 2, cy = (1 + P12) h / 2.
    """
    fx = proj[0][0] * w / 2.0
    fy = proj[1][1] * h / 2.0
    cx = (1.0 - proj[0][2]) * w / 2.0
    cy = (1.0 + proj[1][2]) * h / 2.0
    return fx, fy, cx, cy


def render_size(scene):
    """The rendered image size in pixels: resolution x percentage."""
    r = scene.render
    pct = r.resolution_percentage / 100.0
    return int(r.resolution_x * pct), int(r.resolution_y * pct)


def camera_intrinsics(cam_data, w, h, pixel_aspect=(1.0, 1.0)):
    """Pinhole intrinsics (fx, fy, cx, cy; pixels, OpenCV corner convention) of a Blender
    perspective camera rendering w x h pixels, in double precision, from its lens, sensor size
    and fit (AUTO fits the sensor width to the larger side), shift and the pixel aspect, as
    Blender's view plane is computed (`BKE_camera_params_compute_viewplane`)."""
    if cam_data.type != "PERSP":
        raise ValueError(f"camera '{cam_data.name}' is {cam_data.type}, not perspective")
    ax, ay = pixel_aspect
    ycor = ay / ax
    fit = cam_data.sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if w * ax >= h * ay else "VERTICAL"
        sensor = cam_data.sensor_width
    else:
        sensor = cam_data.sensor_width if fit == "HORIZONTAL" else cam_data.sensor_height
    # The view plane spans viewfac x-units over the fitted side; a pixel is 1 x-unit wide and
    # ycor x-units high.
    viewfac = w if fit == "HORIZONTAL" else ycor * h
    fx = cam_data.lens / sensor * viewfac
    fy = fx / ycor
    cx = 0.5 * w - cam_data.shift_x * viewfac
    cy = 0.5 * h + cam_data.shift_y * viewfac / ycor
    return fx, fy, cx, cy


def vertical_fov_degrees(cam_data, w, h, pixel_aspect=(1.0, 1.0)):
    """The vertical field of view of a Blender perspective camera rendering w x h pixels."""
    fy = camera_intrinsics(cam_data, w, h, pixel_aspect)[1]
    return math.degrees(2.0 * math.atan(0.5 * h / fy))


def quaternion_wxyz(q):
    """A mathutils Quaternion as a list [w, x, y, z] with w >= 0 (the same rotation)."""
    q = q.normalized()
    if q.w < 0:
        q = Quaternion((-q.w, -q.x, -q.y, -q.z))
    return [q.w, q.x, q.y, q.z]


def opencv_project(points, c2w_gl, fx, fy, cx, cy):
    """objnerf's projection (OpenCV pinhole, pixel (0, 0) = top-left corner) of world points
    (N x 3 array-like) through a camera given as an OpenGL camera-to-world 4x4. Returns an
    N x 3 numpy array of (u, v, z), z the camera z-depth (positive in front)."""
    import numpy as np

    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    m = np.array(c2w_gl, dtype=np.float64)
    r, t = m[:3, :3], m[:3, 3]
    cam = (pts - t) @ r  # world -> OpenGL camera (rows: r^T (p - t))
    x, y, z = cam[:, 0], -cam[:, 1], -cam[:, 2]  # OpenGL camera -> OpenCV camera
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.stack([fx * x / z + cx, fy * y / z + cy, z], axis=1)
