"""Importing the demo `extract` run: cameras that project like objnerf's, the proxy on its points,
and the bad cases (missing folder, missing files, a scene format that needs the exporter)."""

import json
import os
import shutil
import struct

import bpy
import numpy as np
import pytest
from conftest import blender_report, scene_objects
from mathutils.bvhtree import BVHTree
from objnerf_blender import cli, formats, frames


def blender_project(cam, pts_world, w, h):
    """Pixels (OpenCV corner convention) of world points through a Blender camera, computed
    with Blender's own matrices: projection (lens, sensor, shift, pixel aspect) and view."""
    scene = bpy.context.scene
    dg = bpy.context.evaluated_depsgraph_get()
    proj = cam.evaluated_get(dg).calc_matrix_camera(
        dg, x=w, y=h, scale_x=scene.render.pixel_aspect_x, scale_y=scene.render.pixel_aspect_y)
    m = np.array(proj @ cam.matrix_world.inverted(), dtype=np.float64)
    hom = np.c_[pts_world, np.ones(len(pts_world))] @ m.T
    ndc = hom[:, :3] / hom[:, 3:4]
    return np.stack([(ndc[:, 0] + 1) * w / 2, (1 - ndc[:, 1]) * h / 2], axis=1)


def world_points(obj):
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    m = np.array(obj.matrix_world, dtype=np.float64)
    return np.c_[co.reshape(-1, 3), np.ones(len(co) // 3)] @ m.T[:, :3]


def test_demo_run_cameras_project_like_objnerf(prefs, demo_run):
    assert bpy.ops.objnerf.import_run(directory=os.path.join(demo_run, "run")) == {"FINISHED"}
    cams = scene_objects("CAMERA")
    assert len(cams) == 36
    root = scene_objects("ROOT")[0]
    # The demo capture is +Z up: the parent maps the capture frame to Blender's world unchanged.
    assert np.allclose(np.array(root.matrix_world), np.eye(4), atol=1e-6)
    tf = formats.read_transforms(os.path.join(demo_run, "scene", "transforms.json"))
    sparse = next(o for o in scene_objects("POINTS") if o.name.endswith("sparse"))
    xyz, _, _ = formats.read_ply(tf["ply"])
    pts_blender = world_points(sparse)
    assert len(pts_blender) == len(xyz) == 4489
    worst, n = 0.0, 0
    by_name = {c.name: c for c in cams}
    for fr in tf["frames"]:
        cam = by_name[fr["name"]]
        ours = frames.opencv_project(xyz, fr["c2w"], fr["fx"], fr["fy"], fr["cx"], fr["cy"])
        keep = (ours[:, 2] > 0) & (ours[:, 0] >= 0) & (ours[:, 0] < fr["w"]) & (ours[:, 1] >= 0) & (ours[:, 1] < fr["h"])
        theirs = blender_project(cam, pts_blender[keep], fr["w"], fr["h"])
        err = np.linalg.norm(theirs - ours[keep, :2], axis=1)
        worst, n = max(worst, float(err.max())), n + int(keep.sum())
    print(f"reprojection: {n} point-views over 36 cameras, max |Blender - objnerf| = {worst:.2e} px")
    assert n > 36 * 1000
    assert worst < 0.5
    # objnerf's own projections: the demo scene's COLMAP features are the points projected by
    # objnerf (src/demo/tracks.rs: no noise, no outliers by default), in COLMAP's pixel frame.
    feats, xyz_by_id = read_colmap_tracks(os.path.join(demo_run, "scene", "sparse", "0"))
    worst_f, n_f = 0.0, 0
    root_m = np.array(root.matrix_world, dtype=np.float64)
    for name, obs in feats.items():
        pts = np.array([xyz_by_id[pid] for _, _, pid in obs])
        pts_world = np.c_[pts, np.ones(len(pts))] @ root_m.T[:, :3]
        theirs = blender_project(by_name[os.path.splitext(os.path.basename(name))[0]], pts_world, 320, 240)
        err = np.linalg.norm(theirs - np.array([(x, y) for x, y, _ in obs]), axis=1)
        worst_f, n_f = max(worst_f, float(err.max())), n_f + len(obs)
    print(f"against objnerf's features (sparse/0/images.bin): {n_f} observations over {len(feats)} cameras, "
          f"max |Blender - objnerf| = {worst_f:.2e} px")
    assert len(feats) == 36 and n_f > 36 * 1000
    assert worst_f < 0.5


def read_colmap_tracks(model):
    """COLMAP binary images.bin / points3D.bin (layout in ../shared/DESIGN.md): per image name,
    its observations (x, y, point3D_id) of triangulated points; and point id -> xyz."""
    with open(os.path.join(model, "points3D.bin"), "rb") as f:
        data = f.read()
    (n,), off, xyz = struct.unpack_from("<Q", data), 8, {}
    for _ in range(n):
        pid, x, y, z = struct.unpack_from("<Q3d", data, off)
        track_len = struct.unpack_from("<Q", data, off + 43)[0]
        xyz[pid], off = (x, y, z), off + 51 + 8 * track_len
    with open(os.path.join(model, "images.bin"), "rb") as f:
        data = f.read()
    (n,), off, feats = struct.unpack_from("<Q", data), 8, {}
    for _ in range(n):
        off += 4 + 7 * 8 + 4
        end = data.index(b"\0", off)
        name, off = data[off:end].decode(), end + 1
        (n2d,) = struct.unpack_from("<Q", data, off)
        off += 8
        obs = [struct.unpack_from("<2dq", data, off + 24 * k) for k in range(n2d)]
        feats[name], off = [o for o in obs if o[2] >= 0], off + 24 * n2d
    return feats, xyz
    r = bpy.context.scene.render
    assert (r.resolution_x, r.resolution_y, r.resolution_percentage) == (320, 240, 100)


def test_mug_proxy_sits_on_its_segmented_points(prefs, demo_run):
    run = os.path.join(demo_run, "run")
    bpy.ops.objnerf.import_run(directory=run, backgrounds=False)
    mug = next(o for o in scene_objects("PROXY") if o.name == "mug")
    header = formats.read_objf_header(os.path.join(run, "mug", "model.objf"))
    piv = formats.model_pivot(header)
    assert np.allclose(mug.location, piv, atol=1e-6)  # origin at the pivot, the box centre
    assert np.allclose(mug["objnerf_pivot"], piv, atol=0)
    seg = next(o for o in scene_objects("POINTS") if o.name == "mug points")
    pts = world_points(seg)
    dg = bpy.context.evaluated_depsgraph_get()
    bvh = BVHTree.FromObject(mug, dg)
    inv = np.array(mug.matrix_world.inverted(), dtype=np.float64)
    local = np.c_[pts, np.ones(len(pts))] @ inv.T[:, :3]
    d = np.array([bvh.find_nearest(p)[3] for p in local])
    size = mug.dimensions.length
    print(f"mug proxy: {len(d)} segmented points, mean distance {d.mean():.5f} = "
          f"{100 * d.mean() / size:.2f}% of its size {size:.4f} (median {np.median(d):.5f})")
    assert d.mean() < 0.01 * size


def test_missing_run_folder_is_a_report(addon, tmp_path):
    with blender_report("does not exist"):
        bpy.ops.objnerf.import_run(directory=str(tmp_path / "nope"))
    assert not scene_objects("ROOT")


def test_run_missing_files_is_a_report(addon, demo_run, tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    shutil.copy(os.path.join(demo_run, "run", "report.json"), run / "report.json")
    with blender_report(r"missing mug/model\.objf, mug/mesh\.ply, segment/mug_points\.ply"):
        bpy.ops.objnerf.import_run(directory=str(run))
    (run / "report.json").write_text("{not json")
    with blender_report("not valid JSON"):
        bpy.ops.objnerf.import_run(directory=str(run))
    assert not scene_objects("ROOT")


def test_import_scene_and_other_formats(prefs, objnerf_bin, demo_run):
    scene = os.path.join(demo_run, "scene")
    assert bpy.ops.objnerf.import_scene(filepath=os.path.join(scene, "transforms.json")) == {"FINISHED"}
    assert len(scene_objects("CAMERA")) == 36
    # A COLMAP model goes through `objnerf export nerfstudio` (issue 15): until that command
    # exists the import is a clear report.
    colmap = os.path.join(scene, "sparse", "0")
    if cli.has_command(objnerf_bin, "export"):
        assert bpy.ops.objnerf.import_scene(filepath=colmap) == {"FINISHED"}
        assert len(scene_objects("CAMERA")) == 72
    else:
        with pytest.raises(RuntimeError, match="objnerf export nerfstudio"):
            bpy.ops.objnerf.import_scene(filepath=colmap)


def test_binary_not_found_is_a_report(addon, tmp_path):
    p = bpy.context.preferences.addons["objnerf_blender"].preferences
    p.binary = str(tmp_path / "no-such-objnerf")
    with blender_report("objnerf binary not found"):
        bpy.ops.objnerf.import_scene(filepath=str(tmp_path))  # a folder without transforms.json


def test_proxy_silhouette_matches_objnerf_render(prefs, objnerf_bin, demo_run, tmp_path):
    """Conventions end to end with today's binary: `objnerf render` of the mug's field from the
    scene's cameras against Blender's render of the imported proxy through the imported cameras
    (frames, pivot, intrinsics, image rows). IoU of the silhouettes per view."""
    import subprocess

    run = os.path.join(demo_run, "run")
    out = tmp_path / "objnerf"
    subprocess.run([objnerf_bin, "render", os.path.join(run, "mug", "model.objf"), "--scene",
                    os.path.join(demo_run, "scene"), "--out", str(out), "--downscale", "2"],
                   check=True, capture_output=True)
    bpy.ops.objnerf.import_run(directory=run, backgrounds=False)
    scene = bpy.context.scene
    for c in bpy.data.collections:
        c.hide_render = False
    for o in scene.objects:
        o.hide_render = o.name != "mug"
    r = scene.render
    r.resolution_percentage, r.engine, r.film_transparent = 50, "BLENDER_WORKBENCH", True
    r.image_settings.color_mode = "RGBA"
    ious = []
    for cam in sorted(scene_objects("CAMERA"), key=lambda c: c.name)[::3]:
        scene.camera = cam
        r.filepath = str(tmp_path / f"blender_{cam.name}.png")
        bpy.ops.render.render(write_still=True)
        mine = _read(r.filepath)[..., 3] > 0.5
        theirs = _read(str(out / f"{cam.name}_alpha.png"))[..., 0] > 0.5
        assert mine.shape == theirs.shape == (120, 160)
        ious.append((mine & theirs).sum() / max(1, (mine | theirs).sum()))
    print(f"mug proxy (Blender, Workbench) vs objnerf render alpha, 12 views at 160x120: "
          f"IoU min {min(ious):.3f}, mean {np.mean(ious):.3f}")
    # A convention error (axes, pivot, pixel centres, rows) drops every view well below this;
    # one view's min sits near 0.9 since extract keeps views back from training (min 0.897,
    # mean 0.94 at 160x120, where a one-pixel rim is a tenth of the mug's silhouette).
    assert np.mean(ious) >= 0.9 and min(ious) >= 0.85


def _read(path):
    img = bpy.data.images.load(path, check_existing=False)
    img.colorspace_settings.name = "Non-Color"
    w, h = img.size
    a = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(a)
    bpy.data.images.remove(img)
    return a.reshape(h, w, 4)[::-1]


def test_distortion_is_noted_not_faked(addon, demo_run, tmp_path):
    tf = json.load(open(os.path.join(demo_run, "scene", "transforms.json")))
    tf.update(camera_model="OPENCV", k1=-0.05, p2=0.001)
    tf.pop("ply_file_path")
    for fr in tf["frames"]:
        fr["file_path"] = os.path.join(demo_run, "scene", fr["file_path"])
        fr.pop("depth_file_path", None)
    path = tmp_path / "transforms.json"
    path.write_text(json.dumps(tf))
    assert bpy.ops.objnerf.import_scene(filepath=str(path), backgrounds=False) == {"FINISHED"}
    cam = scene_objects("CAMERA")[0]
    assert cam["objnerf_camera_model"] == "OPENCV"
    assert dict(cam["objnerf_distortion"]) == {"k1": -0.05, "p2": 0.001}
    assert cam.data.lens == pytest.approx(336.0 / 320.0 * 36.0) and cam.data.shift_x == 0.0
