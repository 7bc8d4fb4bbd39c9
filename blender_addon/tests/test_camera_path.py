"""camera_path.json from an animated Blender camera: read back by the add-on's reader, by objnerf
(`objnerf camera-path --json`) and by nerfstudio's `get_path_from_json` (with
OBJNERF_NERFSTUDIO_PYTHON, as scripts/check-nerfstudio runs it), every frame is the camera Blender
renders (pose in the capture frame, intrinsics from Blender's projection). Given a nerfstudio
run's dataparser_transforms.json the path is in nerfstudio's viewer frame, and says so."""

import json
import math
import os
import subprocess
import sys

import bpy
import numpy as np
import pytest
from conftest import ROOT, blender_report, scene_objects, skip
from mathutils import Matrix, Vector
from objnerf_blender import camera_path, frames, importer

sys.path.insert(0, os.path.join(ROOT, "tests", "nerfstudio"))
from with_applied_transform import COLMAP_APPLIED, with_applied_transform  # noqa: E402


def orbit_camera(n=24, radius=1.6, height=0.9, lens=(30.0, 42.0)):
    """A camera keyframed on a circle around the origin, looking at it, its lens zooming."""
    scene = bpy.context.scene
    cam = bpy.data.objects.new("orbit", bpy.data.cameras.new("orbit"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.frame_start, scene.frame_end = 1, n
    for i in range(n):
        a = 2 * math.pi * i / n
        pos = Vector((radius * math.cos(a), radius * math.sin(a), height))
        cam.location = pos
        cam.rotation_euler = (-pos).to_track_quat("-Z", "Y").to_euler()
        cam.data.lens = lens[0] + (lens[1] - lens[0]) * i / (n - 1)
        cam.keyframe_insert("location", frame=i + 1)
        cam.keyframe_insert("rotation_euler", frame=i + 1)
        cam.data.keyframe_insert("lens", frame=i + 1)
    return cam


def blender_intrinsics(cam, w, h):
    dg = bpy.context.evaluated_depsgraph_get()
    proj = cam.evaluated_get(dg).calc_matrix_camera(dg, x=w, y=h, scale_x=1, scale_y=1)
    return frames.projection_intrinsics(proj, w, h)


def authored_path(demo_run, tmp_path):
    """The demo run imported under a turned and moved parent, a keyframed 24-frame orbit exported
    as camera_path.json at 160x120 (320x240 at 50%). Returns the file, Blender's cameras per frame
    in the capture frame ({"c2w": rigid root^-1 @ matrix_world, "k": (fx, fy, cx, cy) from
    Blender's projection matrix}), the root and the camera."""
    bpy.ops.objnerf.import_run(directory=os.path.join(demo_run, "run"), backgrounds=False)
    root = scene_objects("ROOT")[0]
    # A capture that is not +Z up (as COLMAP gives): the parent turns and moves it, and the
    # path must still come out in the capture frame.
    root.matrix_world = Matrix.Translation((0.3, -0.1, 0.2)) @ Matrix.Rotation(math.radians(-90), 4, "X")
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 320, 240, 50
    scene.render.fps, scene.render.fps_base = 30, 1.001
    cam = orbit_camera()
    out = tmp_path / "camera_path.json"
    assert bpy.ops.objnerf.export_camera_path(filepath=str(out)) == {"FINISHED"}
    want = []
    for i in range(24):
        scene.frame_set(i + 1)
        want.append({"c2w": np.array(frames.rigid_part(root.matrix_world.inverted() @ cam.matrix_world)),
                     "k": blender_intrinsics(cam, 160, 120)})
    scene.frame_set(1)
    return out, want, root, cam


def compare(cameras, want):
    """Worst |c2w difference| and worst intrinsics difference (relative to fx) of `cameras`
    ([{"c2w": 4x4 or 16 row-major, "fx", "fy", "cx", "cy"}]) against Blender's."""
    assert len(cameras) == len(want) == 24
    worst_m, worst_k = 0.0, 0.0
    for c, w in zip(cameras, want):
        m = np.asarray(c["c2w"], dtype=np.float64).reshape(-1, 4)[:3]
        worst_m = max(worst_m, np.abs(m - w["c2w"][:3]).max())
        # Relative to fx: Blender's projection matrix is single precision.
        got = (c["fx"], c["fy"], c["cx"], c["cy"])
        worst_k = max(worst_k, max(abs(a - b) / c["fx"] for a, b in zip(got, w["k"])))
    return worst_m, worst_k


def test_camera_path_reads_back_to_blenders_cameras(prefs, demo_run, tmp_path):
    out, want, root, cam = authored_path(demo_run, tmp_path)
    doc = json.loads(out.read_text())
    assert doc["objnerf_frame"] == "data"
    assert doc["camera_type"] == "perspective"
    assert (doc["render_width"], doc["render_height"]) == (160, 120)
    assert doc["fps"] == pytest.approx(30 / 1.001) and doc["seconds"] == pytest.approx(24 * 1.001 / 30)
    path = camera_path.read_camera_path(str(out))
    worst_m, worst_k = compare(path, want)
    scene = bpy.context.scene
    pts = np.random.default_rng(0).uniform(-0.3, 0.3, (50, 3))  # capture frame
    worst_px = 0.0
    for i, c in enumerate(path):
        scene.frame_set(i + 1)
        # Pixels of the same points: through Blender (world) and through the path (capture).
        world = np.c_[pts, np.ones(len(pts))] @ np.array(root.matrix_world).T[:, :3]
        dg = bpy.context.evaluated_depsgraph_get()
        proj = cam.evaluated_get(dg).calc_matrix_camera(dg, x=160, y=120)
        hom = np.c_[world, np.ones(len(world))] @ np.array(proj @ cam.matrix_world.inverted()).T
        ndc = hom[:, :2] / hom[:, 3:4]
        theirs = np.stack([(ndc[:, 0] + 1) * 80, (1 - ndc[:, 1]) * 60], axis=1)
        ours = frames.opencv_project(pts, c["c2w"], c["fx"], c["fy"], c["cx"], c["cy"])[:, :2]
        worst_px = max(worst_px, np.abs(theirs - ours).max())
    scene.frame_set(1)
    print(f"camera path: 24 frames, max |c2w| diff {worst_m:.1e}, max intrinsics diff {worst_k:.1e} fx, "
          f"max pixel diff {worst_px:.1e} px")
    assert worst_m < 1e-6 and worst_k < 1e-6 and worst_px < 1e-3


def test_camera_path_reads_back_in_objnerf(prefs, demo_run, tmp_path):
    """objnerf's own reader (`objnerf camera-path FILE --json`, src/scene/camera_path.rs) gives
    Blender's cameras back to 1e-6."""
    out, want, _, _ = authored_path(demo_run, tmp_path)
    doc = json.loads(subprocess.run([prefs.binary, "camera-path", str(out), "--json"], check=True,
                                    capture_output=True, text=True).stdout)
    assert (doc["render_width"], doc["render_height"], doc["camera_type"]) == (160, 120, "perspective")
    cams = [dict(c, c2w=c["camera_to_world"]) for c in doc["cameras"]]
    assert all((c["width"], c["height"]) == (160, 120) for c in cams)
    worst_m, worst_k = compare(cams, want)
    print(f"camera path read by objnerf: 24 cameras, max |c2w| diff {worst_m:.1e}, "
          f"max intrinsics diff {worst_k:.1e} fx")
    assert worst_m < 1e-6 and worst_k < 1e-6


def test_camera_path_reads_back_in_nerfstudio(prefs, demo_run, tmp_path):
    """nerfstudio's own `get_path_from_json` (what ns-render reads) gives Blender's cameras back
    to 1e-6. Needs nerfstudio: scripts/check-nerfstudio runs this test with
    OBJNERF_NERFSTUDIO_PYTHON set; without it the test skips."""
    py = os.environ.get("OBJNERF_NERFSTUDIO_PYTHON")
    if not py:
        skip("OBJNERF_NERFSTUDIO_PYTHON is not set (scripts/check-nerfstudio runs this test)")
    out, want, _, _ = authored_path(demo_run, tmp_path)
    jobs, results = tmp_path / "jobs.json", tmp_path / "results.json"
    jobs.write_text(json.dumps({"jobs": [{"kind": "path", "file": str(out)}]}))
    subprocess.run([py, os.path.join(ROOT, "tests", "nerfstudio", "ns_check.py"), str(jobs), str(results)],
                   check=True)
    seen = json.loads(results.read_text())["results"][0]
    cams = [{"c2w": seen["c2w"][i], **{k: seen[k][i] for k in ("fx", "fy", "cx", "cy")}} for i in range(24)]
    assert set(seen["width"]) == {160} and set(seen["height"]) == {120}
    assert set(seen["camera_type"]) == {"PERSPECTIVE"}
    worst_m, worst_k = compare(cams, want)
    # nerfstudio holds cameras in float32.
    print(f"camera path read by nerfstudio (get_path_from_json): 24 cameras, max |c2w| diff {worst_m:.1e}, "
          f"max intrinsics diff {worst_k:.1e} fx")
    assert worst_m < 1e-6 and worst_k < 1e-6


# ------------------------------------------------------------------ nerfstudio's viewer frame

def to_viewer(c2w, transform, scale, applied):
    """Worked in numpy: a capture-frame camera-to-world (4x4, OpenGL) in nerfstudio's viewer frame,
    scale * T * A^-1 applied and the scale taken out of the camera's axes."""
    four = lambda m: np.vstack([np.asarray(m, dtype=np.float64), [0.0, 0.0, 0.0, 1.0]])
    m = scale * four(transform) @ np.linalg.inv(four(applied)) @ np.asarray(c2w, dtype=np.float64)
    m[:3, :3] /= scale
    m[3] = [0.0, 0.0, 0.0, 1.0]
    return m


def import_for_path(scene_json):
    """The scene's cameras (no points) under a turned and moved root, and a 24-frame orbit camera."""
    root, *_ = importer.import_scene(bpy.context, scene_json, points=False, backgrounds=False)
    root.matrix_world = Matrix.Translation((0.3, -0.1, 0.2)) @ Matrix.Rotation(math.radians(-90), 4, "X")
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 320, 240, 50
    return root, orbit_camera()


def blender_cameras(root, cam, n):
    """Blender's cameras per frame: rigid root^-1 @ matrix_world and (fx, fy, cx, cy) at 160x120."""
    scene, want = bpy.context.scene, []
    for i in range(n):
        scene.frame_set(i + 1)
        want.append({"c2w": np.array(frames.rigid_part(root.matrix_world.inverted() @ cam.matrix_world)),
                     "k": blender_intrinsics(cam, 160, 120)})
    scene.frame_set(1)
    return want


def test_camera_path_in_nerfstudios_viewer_frame(prefs, demo_run, tmp_path):
    """With a run's dataparser_transforms.json (a known turn, move and scale) and a dataset with an
    applied_transform, each camera of the file is Blender's taken by scale * T * A^-1, worked out
    here in numpy (1e-6), and the file says "viewer"; its field of view is Blender's."""
    scene_json = with_applied_transform(os.path.join(demo_run, "scene", "transforms.json"), str(tmp_path / "scene"))
    root, cam = import_for_path(scene_json)
    turn = Matrix.Rotation(0.7, 3, Vector((0.3, -0.5, 0.8)).normalized())
    transform = [[*turn[r], (0.4, -1.2, 0.35)[r]] for r in range(3)]
    dpt = tmp_path / "dataparser_transforms.json"
    dpt.write_text(json.dumps({"transform": transform, "scale": 0.37}, indent=4))
    out = tmp_path / "viewer_path.json"
    assert bpy.ops.objnerf.export_camera_path(filepath=str(out), dataparser_transforms=str(dpt)) == {"FINISHED"}
    doc = json.loads(out.read_text())
    assert doc["objnerf_frame"] == "viewer" and (doc["render_width"], doc["render_height"]) == (160, 120)
    want = blender_cameras(root, cam, 24)
    worst_m, worst_k = compare(camera_path.read_camera_path(str(out)),
                               [dict(w, c2w=to_viewer(w["c2w"], transform, 0.37, COLMAP_APPLIED)) for w in want])
    # Without the dataset's applied_transform the cameras would be elsewhere: it is used.
    moved = np.abs(np.array(doc["camera_path"][0]["camera_to_world"]).reshape(4, 4)
                   - to_viewer(want[0]["c2w"], transform, 0.37, np.eye(4)[:3])).max()
    print(f"camera path in the viewer frame: 24 frames, max |c2w| diff {worst_m:.1e} from scale * T * A^-1, "
          f"max intrinsics diff {worst_k:.1e} fx; {moved:.2f} off without A")
    assert worst_m < 1e-6 and worst_k < 1e-6 and moved > 0.1


def test_bad_dataparser_transforms_are_reported_and_nothing_is_written(prefs, demo_run, tmp_path):
    import_for_path(os.path.join(demo_run, "scene", "transforms.json"))
    out = tmp_path / "out" / "camera_path.json"
    dpt = tmp_path / "dataparser_transforms.json"
    with blender_report("no such file"):
        bpy.ops.objnerf.export_camera_path(filepath=str(out), dataparser_transforms=str(dpt))
    dpt.write_text(json.dumps({"transform": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]], "scale": 1.0}))
    with blender_report("dataparser_transforms.json.*uniform scale"):
        bpy.ops.objnerf.export_camera_path(filepath=str(out), dataparser_transforms=str(dpt))
    assert not out.parent.exists() or os.listdir(out.parent) == []


def test_viewer_frame_path_reads_back_in_nerfstudio(prefs, tmp_path):
    """The check of issue 52, run by scripts/check-nerfstudio (skips without its environment): a
    path authored here on an exported nerfstudio dataset with an applied_transform, written with
    the dataparser_transforms.json of a real ns-train run, read by nerfstudio's own
    get_path_from_json, gives Blender's cameras to 1e-4 (c2w and intrinsics):
      - every frame, taken back by nerfstudio's transform_poses_to_original_space, is Blender's
        camera in nerfstudio's original frame (A^-1 of the capture frame);
      - the frames placed at dataset views are, as read, the viewer-frame cameras nerfstudio's own
        dataparser makes of those views (its transform checked equal to the run's).
    Environment: OBJNERF_NERFSTUDIO_PYTHON, OBJNERF_NS_DATASET (the export) and
    OBJNERF_NS_DATAPARSER_TRANSFORMS (the run's file)."""
    env = [os.environ.get(k) for k in ("OBJNERF_NERFSTUDIO_PYTHON", "OBJNERF_NS_DATASET",
                                       "OBJNERF_NS_DATAPARSER_TRANSFORMS")]
    if not all(env):
        skip("OBJNERF_NERFSTUDIO_PYTHON, OBJNERF_NS_DATASET or OBJNERF_NS_DATAPARSER_TRANSFORMS is not set "
             "(scripts/check-nerfstudio sets them)")
    py, data, dpt = env
    tf = json.loads(open(os.path.join(data, "transforms.json"), encoding="utf-8").read())
    assert tf.get("applied_transform") is not None, "the dataset should carry an applied_transform"
    root, cam = import_for_path(os.path.join(data, "transforms.json"))
    views = sorted(scene_objects("CAMERA"), key=lambda o: o.name)[::6][:6]
    bpy.context.view_layer.update()  # the views' matrix_world under the moved root
    for i, v in enumerate(views):  # the orbit's first frames move onto dataset views
        cam.matrix_world = v.matrix_world
        cam.keyframe_insert("location", frame=i + 1)
        cam.keyframe_insert("rotation_euler", frame=i + 1)
    out = tmp_path / "viewer_path.json"
    assert bpy.ops.objnerf.export_camera_path(filepath=str(out), dataparser_transforms=dpt) == {"FINISHED"}
    assert json.loads(out.read_text())["objnerf_frame"] == "viewer"
    want = blender_cameras(root, cam, 24)
    jobs, results = tmp_path / "jobs.json", tmp_path / "results.json"
    jobs.write_text(json.dumps({"jobs": [{"kind": "path", "file": str(out), "to_original": dpt},
                                         {"kind": "path", "file": str(out)},
                                         {"kind": "dataparser", "data": data}]}))
    subprocess.run([py, os.path.join(ROOT, "tests", "nerfstudio", "ns_check.py"), str(jobs), str(results)],
                   check=True)
    original, viewer, parser = json.loads(results.read_text())["results"]
    cams = lambda seen, n: [{"c2w": seen["c2w"][i], **{k: seen[k][i] for k in ("fx", "fy", "cx", "cy")}}
                            for i in range(n)]
    assert set(original["width"]) == {160} and set(original["height"]) == {120}
    undo_a = np.linalg.inv(np.vstack([np.array(tf["applied_transform"], dtype=np.float64), [0, 0, 0, 1]]))
    worst_m, worst_k = compare(cams(original, 24), [dict(w, c2w=undo_a @ w["c2w"]) for w in want])
    run_t = json.loads(open(dpt, encoding="utf-8").read())
    t_diff = max(np.abs(np.array(parser["transform"]) - np.array(run_t["transform"])[:3]).max(),
                 abs(parser["scale"] - run_t["scale"]))
    by_name = {os.path.basename(f): i for i, f in enumerate(parser["image_filenames"])}
    worst_v = 0.0
    for i, v in enumerate(views):
        j = by_name[os.path.basename(v["objnerf_image"])]
        worst_v = max(worst_v, np.abs(np.array(viewer["c2w"][i]) - np.array(parser["c2w"][j])).max())
    print(f"nerfstudio's get_path_from_json on a Blender {bpy.app.version_string} path in the viewer frame of "
          f"{dpt}:\n  24 frames back in the original frame (transform_poses_to_original_space): "
          f"max |c2w diff| {worst_m:.1e}, max intrinsics diff {worst_k:.1e} fx\n  {len(views)} frames at dataset "
          f"views against nerfstudio's dataparser cameras (viewer frame): max |c2w diff| {worst_v:.1e}; "
          f"its transform and scale against the run's: {t_diff:.1e}")
    assert worst_m < 1e-4 and worst_k < 1e-4 and worst_v < 1e-4 and t_diff < 1e-6


@pytest.mark.parametrize("fit,size,aspect", [
    ("AUTO", (320, 240), (1, 1)), ("AUTO", (240, 320), (1, 1)), ("HORIZONTAL", (240, 320), (1, 1)),
    ("VERTICAL", (320, 240), (1, 1)), ("VERTICAL", (200, 300), (1, 1)), ("AUTO", (320, 240), (1.0, 1.3)),
    ("AUTO", (240, 320), (1.4, 1.0)), ("HORIZONTAL", (320, 240), (1.0, 1.2)), ("VERTICAL", (320, 240), (1.25, 1.0))])
def test_intrinsics_match_blenders_projection(addon, fit, size, aspect):
    """frames.camera_intrinsics (double precision, from the camera's settings) against Blender's own
    projection matrix, with lens shift, every sensor fit and non-square pixels."""
    data = bpy.data.cameras.new("c")
    data.sensor_fit, data.lens, data.sensor_width, data.sensor_height = fit, 28.0, 36.0, 20.0
    data.shift_x, data.shift_y = 0.04, -0.07
    cam = bpy.data.objects.new("c", data)
    bpy.context.scene.collection.objects.link(cam)
    w, h = size
    dg = bpy.context.evaluated_depsgraph_get()
    proj = cam.evaluated_get(dg).calc_matrix_camera(dg, x=w, y=h, scale_x=aspect[0], scale_y=aspect[1])
    want = frames.projection_intrinsics(proj, w, h)
    got = frames.camera_intrinsics(data, w, h, aspect)
    assert np.allclose(got, want, rtol=1e-6), (got, want)  # Blender's matrix is single precision
    if aspect == (1, 1):
        assert frames.vertical_fov_degrees(data, w, h) == pytest.approx(math.degrees(2 * math.atan(h / 2 / want[1])), rel=1e-6)


def test_intrinsics_round_trip_through_a_blender_camera(addon):
    """fx != fy and an off-centre principal point: Blender's projection gives them back."""
    scene = bpy.context.scene
    for (fx, fy, cx, cy, w, h) in ((300.0, 300.0, 171.5, 112.25, 320, 240), (410.0, 380.0, 150.0, 200.0, 300, 420),
                                   (250.0, 290.0, 160.0, 100.0, 320, 240)):
        data = bpy.data.cameras.new("c")
        ax, ay = frames.apply_intrinsics(data, fx, fy, cx, cy, w, h)
        cam = bpy.data.objects.new("c", data)
        scene.collection.objects.link(cam)
        dg = bpy.context.evaluated_depsgraph_get()
        proj = cam.evaluated_get(dg).calc_matrix_camera(dg, x=w, y=h, scale_x=ax, scale_y=ay)
        got = frames.projection_intrinsics(proj, w, h)
        assert np.allclose(got, (fx, fy, cx, cy), atol=1e-3), (got, (fx, fy, cx, cy))


def test_camera_path_refuses_shift_and_non_square_pixels(prefs, demo_run, tmp_path):
    bpy.ops.objnerf.import_run(directory=os.path.join(demo_run, "run"), backgrounds=False)
    cam = orbit_camera(n=3)
    cam.data.shift_x = 0.1
    with pytest.raises(RuntimeError, match="lens shift"):
        bpy.ops.objnerf.export_camera_path(filepath=str(tmp_path / "p.json"))
    cam.data.shift_x = 0.0
    bpy.context.scene.render.pixel_aspect_x = 2.0
    with pytest.raises(RuntimeError, match="square pixels"):
        bpy.ops.objnerf.export_camera_path(filepath=str(tmp_path / "p.json"))
