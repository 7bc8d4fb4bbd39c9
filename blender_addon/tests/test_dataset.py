"""A Blender scene exported as a nerfstudio dataset: the truth is exact (depth and masks agree with
the known geometry through the exported cameras); the add-on's transforms.json and objnerf's
(`objnerf export nerfstudio`) are one format, read both ways with Blender's cameras and depth
unchanged; objnerf's one-click segmentation (after `objnerf sfm`) matches the Blender mask pass."""

import json
import os
import subprocess

import addon_utils
import bpy
import numpy as np
import pytest
from conftest import MODULE, scene_objects
from objnerf_blender import compat, formats, frames

SIZE = (320, 240)
SPHERE = {"location": (0.5, -0.25, 0.35), "radius": 0.35}


def textured_material(name, seed, palette):
    """A material with a random block texture in shades of one hue: corners for SIFT, yet one
    object to SAM (blocks of different hues made SAM pick a part of the sphere; texels of about
    a pixel gave SIFT too little). Workbench shows it."""
    rng = np.random.default_rng(seed)
    n = 48
    img = bpy.data.images.new(name, n, n)
    cols = np.array(palette, dtype=np.float32)[rng.integers(0, len(palette), n * n)]
    img.pixels.foreach_set(np.c_[cols, np.ones(n * n, np.float32)].ravel())
    img.pack()
    mat = bpy.data.materials.new(name)
    compat.material_nodes(mat)
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation = img, "Closest"
    mat.node_tree.links.new(tex.outputs["Color"], mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
    mat.node_tree.nodes.active = tex
    return mat


def build_scene():
    """Ground, cube, UV sphere and torus, each with its own texture."""
    specs = [
        ("Ground", lambda: bpy.ops.mesh.primitive_plane_add(size=3), [(0.5, 0.5, 0.5), (0.3, 0.3, 0.3), (0.7, 0.7, 0.65)]),
        ("Cube", lambda: bpy.ops.mesh.primitive_cube_add(size=0.5, location=(-0.55, 0.35, 0.25)),
         [(0.9, 0.3, 0.1), (0.45, 0.12, 0.04), (1.0, 0.55, 0.3)]),
        ("Sphere", lambda: bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, **SPHERE),
         [(0.1, 0.25, 0.8), (0.04, 0.1, 0.4), (0.35, 0.55, 1.0)]),
        ("Torus", lambda: bpy.ops.mesh.primitive_torus_add(location=(0.25, 0.75, 0.1), major_radius=0.3, minor_radius=0.1),
         [(0.1, 0.6, 0.1), (0.04, 0.3, 0.04), (0.4, 0.9, 0.3)]),
    ]
    for i, (name, add, palette) in enumerate(specs):
        add()
        obj = bpy.context.active_object
        obj.name = name
        obj.data.materials.append(textured_material(name, i, palette))
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100


def read_gray(path):
    img = bpy.data.images.load(path, check_existing=False)
    img.colorspace_settings.name = "Non-Color"
    w, h = img.size
    a = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(a)
    bpy.data.images.remove(img)
    return a.reshape(h, w, 4)[::-1, :, 0]


def blender_cameras(cams, w, h):
    """Blender's own cameras: {name: (c2w 4x4 without scale, (fx, fy, cx, cy) from Blender's
    projection matrix)}."""
    dg = bpy.context.evaluated_depsgraph_get()
    out = {}
    for cam in cams:
        proj = cam.evaluated_get(dg).calc_matrix_camera(dg, x=w, y=h, scale_x=1, scale_y=1)
        loc, rot, _ = cam.matrix_world.decompose()
        c2w = np.eye(4)
        c2w[:3, :3], c2w[:3, 3] = np.array(rot.to_matrix()), np.array(loc)
        out[cam.name] = (c2w, frames.projection_intrinsics(proj, w, h))
    return out


@pytest.fixture(scope="module")
def dataset_and_cameras(tmp_path_factory):
    """The dataset (default options but the light) and Blender's cameras, by frame stem."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon_utils.enable(MODULE, default_set=True, handle_error=None)
    try:
        build_scene()
        out = str(tmp_path_factory.mktemp("dataset"))
        # Flat light: with Workbench's studio light SAM took only the lit part of the sphere in a
        # few views (mIoU 0.921-0.926 over two runs); unshaded, 0.977-0.980.
        res = bpy.ops.objnerf.export_dataset(directory=out, cameras="RING", count=24, lens=30.0, elevation=30.0,
                                               distance=2.6, light="FLAT")
        assert res == {"FINISHED"}
        ring = sorted((o for o in scene_objects("NONE") if o.type == "CAMERA"), key=lambda o: o.name)
        assert len(ring) == 24
        cams = blender_cameras(ring, *SIZE)
    finally:
        addon_utils.disable(MODULE, default_set=True, handle_error=None)
    return out, {f"frame_{i:05d}": cams[c.name] for i, c in enumerate(ring)}


@pytest.fixture(scope="module")
def dataset(dataset_and_cameras):
    return dataset_and_cameras[0]


def test_dataset_truth_is_exact(dataset):
    tf = formats.read_transforms(os.path.join(dataset, "transforms.json"))
    raw = json.load(open(os.path.join(dataset, "transforms.json")))
    # Depth by default: 16-bit PNG millimetres, as nerfstudio reads depth without flags, and said.
    assert raw["depth_unit_scale_factor"] == 1e-3
    assert all(f["depth_file_path"].endswith(".png") for f in raw["frames"])
    objs = json.load(open(os.path.join(dataset, "objects.json")))["objects"]
    assert [o["name"] for o in objs] == ["Cube", "Ground", "Sphere", "Torus"]
    assert len(tf["frames"]) == 24 and (tf["frames"][0]["w"], tf["frames"][0]["h"]) == SIZE
    centre, r = np.array(SPHERE["location"]), SPHERE["radius"]
    worst = 0.0
    for fr in tf["frames"]:
        stem = fr["name"]
        depth = read_depth_png_mm(os.path.join(dataset, "depth", stem + ".png")) / 1000.0
        mask = read_gray(os.path.join(dataset, "masks", "Sphere", stem + ".png")) > 0.5
        assert mask.sum() > 500
        # Every sphere pixel, back-projected with its depth through the exported camera, lies on
        # the sphere: masks, depth (z, millimetres), intrinsics and pose all agree.
        v, u = np.nonzero(mask)
        z = depth[v, u]
        x = (u + 0.5 - fr["cx"]) / fr["fx"] * z
        y = (v + 0.5 - fr["cy"]) / fr["fy"] * z
        c2w = np.array(fr["c2w"])
        world = np.c_[x, -y, -z] @ c2w[:3, :3].T + c2w[:3, 3]  # OpenCV -> OpenGL camera -> world
        err = np.abs(np.linalg.norm(world - centre, axis=1) - r)
        worst = max(worst, float(err.max()))
        # Depth is known exactly where some object is seen, and 0 (unknown) elsewhere.
        seen = np.any([read_gray(os.path.join(dataset, o["masks"], stem + ".png")) > 0.5 for o in objs], axis=0)
        assert np.all(depth[~seen] == 0) and np.all(depth[seen] > 0)
    print(f"dataset: 24 views; sphere pixels back-projected with the depth pass: max |dist - r| = {worst:.2e} m")
    assert worst < 0.01 * r  # the UV sphere's facets are within 0.1% of r (depth to 0.5 mm)


def read_depth_png_mm(path):
    """A 16-bit PNG's values (millimetres), exactly: Blender loads it as v / 65535 floats."""
    mm = read_gray(path) * 65535.0
    assert np.abs(mm - np.rint(mm)).max() < 1e-2, path
    return np.rint(mm)


def same_value(a, b, path):
    if isinstance(a, dict) and isinstance(b, dict):
        assert set(a) == set(b), f"{path}: keys {sorted(a)} vs {sorted(b)}"
        for k in a:
            same_value(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list) and isinstance(b, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            same_value(x, y, f"{path}[{i}]")
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)):
        assert abs(a - b) <= 1e-9 * max(1.0, abs(a)), f"{path}: {a} vs {b}"
    else:
        assert a == b, f"{path}: {a!r} vs {b!r}"


def test_objnerf_and_the_addon_write_one_format(dataset_and_cameras, objnerf_bin, tmp_path):
    """objnerf reads the add-on's transforms.json (`objnerf info`, `objnerf export nerfstudio`)
    with Blender's cameras (1e-5) and depth (to the millimetre, the unit both write by default);
    objnerf's writer rewrites it key for key but `depth_unit_scale_factor`; and the add-on imports
    objnerf's export with Blender's cameras again."""
    dataset, cams = dataset_and_cameras
    ours = json.load(open(os.path.join(dataset, "transforms.json")))
    info = json.loads(subprocess.run([objnerf_bin, "info", dataset, "--json"], check=True, capture_output=True,
                                     text=True).stdout)
    assert info["num_images"] == 24 and info["has_depth"]
    worst_k = 0.0
    for im in info["images"]:
        k = cams[os.path.splitext(os.path.basename(im["name"]))[0]][1]
        assert (im["width"], im["height"]) == SIZE and im["camera_model"] == "PINHOLE"
        worst_k = max(worst_k, max(abs(a - b) / b for a, b in zip((im["fx"], im["fy"], im["cx"], im["cy"]), k)))
    export = tmp_path / "ns"
    subprocess.run([objnerf_bin, "export", "nerfstudio", dataset, "--out", str(export)], check=True,
                   capture_output=True)
    theirs = json.load(open(export / "transforms.json"))
    extra = set(ours) - set(theirs)
    assert extra <= {"depth_unit_scale_factor"}, extra
    same_value({k: ours[k] for k in theirs}, theirs, "transforms.json")
    worst_pose = 0.0
    for fr in theirs["frames"]:
        stem = os.path.splitext(os.path.basename(fr["file_path"]))[0]
        worst_pose = max(worst_pose, float(np.abs(np.array(fr["transform_matrix"]) - cams[stem][0]).max()))
        a = read_depth_png_mm(os.path.join(dataset, "depth", stem + ".png"))
        b = read_depth_png_mm(str(export / fr["depth_file_path"]))
        assert np.array_equal(a, b) and a.max() > 1000, stem
    # Back into Blender: the add-on imports objnerf's export.
    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon_utils.enable(MODULE, default_set=True, handle_error=None)
    try:
        assert bpy.ops.objnerf.import_scene(filepath=str(export / "transforms.json"), backgrounds=False) == {"FINISHED"}
        imported = blender_cameras(scene_objects("CAMERA"), *SIZE)
        root = np.array(scene_objects("ROOT")[0].matrix_world)
    finally:
        addon_utils.disable(MODULE, default_set=True, handle_error=None)
    assert sorted(imported) == sorted(cams)
    worst_back = 0.0
    for name, (c2w, k) in imported.items():
        worst_back = max(worst_back, float(np.abs(np.linalg.inv(root) @ c2w - cams[name][0]).max()),
                         max(abs(a - b) / b for a, b in zip(k, cams[name][1])))
    print(f"add-on -> objnerf: intrinsics max rel. diff {worst_k:.1e}, poses max |diff| {worst_pose:.1e}; "
          f"objnerf -> add-on: max diff {worst_back:.1e}; depth PNGs equal; keys only the add-on writes: {extra}")
    assert worst_k < 1e-5 and worst_pose < 1e-5 and worst_back < 1e-5


def furthest_inside(mask):
    """The pixel of `mask` furthest from its edge (by repeated erosion), as a click x, y."""
    m, last = mask.copy(), mask
    while m.any():
        last = m
        m = m & np.roll(m, 1, 0) & np.roll(m, -1, 0) & np.roll(m, 1, 1) & np.roll(m, -1, 1)
    v, u = np.nonzero(last)
    i = np.argmin((v - v.mean()) ** 2 + (u - u.mean()) ** 2)
    return u[i] + 0.5, v[i] + 0.5


def test_objnerf_reads_and_segments_the_dataset(dataset, objnerf_bin, tmp_path):
    tfj = os.path.join(dataset, "transforms.json")
    info = json.loads(subprocess.run([objnerf_bin, "info", tfj, "--json"], check=True, capture_output=True,
                                     text=True).stdout)
    print("objnerf info:", {k: info[k] for k in list(info)[:6]})
    sfm = str(tmp_path / "sfm")
    subprocess.run(["nice", "-n", "10", objnerf_bin, "sfm", tfj, "--out", sfm], check=True, capture_output=True)
    truth0 = read_gray(os.path.join(dataset, "masks", "Sphere", "frame_00000.png")) > 0.5
    x, y = furthest_inside(truth0)
    seg = str(tmp_path / "seg")
    subprocess.run(["nice", "-n", "10", objnerf_bin, "segment", sfm, "--view", "frame_00000.png", "--object", "sphere",
                    "--point", f"{x},{y}", "--out", seg], check=True, capture_output=True)
    ious = []
    for i in range(24):
        stem = f"frame_{i:05d}"
        truth = read_gray(os.path.join(dataset, "masks", "Sphere", stem + ".png")) > 0.5
        ours_path = os.path.join(seg, "masks", "sphere", stem + ".png")
        ours = read_gray(ours_path) > 0.5 if os.path.isfile(ours_path) else np.zeros_like(truth)
        ious.append((truth & ours).sum() / max(1, (truth | ours).sum()))
    warnings = json.load(open(os.path.join(seg, "report.json")))["warnings"]
    print(f"objnerf segment, one click at ({x}, {y}) in frame_00000: mIoU {np.mean(ious):.3f} over 24 views "
          f"against the Blender mask pass (min {min(ious):.3f}); warnings: {[w['code'] for w in warnings]}")
    # Good or flagged. COLMAP 3.8 seeds its matcher threads from the clock, so each run has other
    # tracks. Over 90 sfm runs of this dataset segmented with one build, 85 scored mIoU
    # 0.955-0.985; in 5 SAM cut the sphere along a shade of its texture in a view that saw a new
    # side, the cut spread over a few views (mIoU 0.842-0.890), and the report warned of it each
    # time (mask_spill, mask_short, mask_beyond_points). A silent result below 0.9, or any below 0.8, fails.
    assert np.mean(ious) >= 0.9 or (np.mean(ious) >= 0.8 and warnings), warnings


def test_selected_cameras_with_their_own_lenses(addon, objnerf_bin, tmp_path):
    """Selected cameras (two lenses: intrinsics per frame), EXR depth in metres, said in
    transforms.json and read so by objnerf."""
    build_scene()
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 64, 48
    cams = []
    for i, (lens, loc) in enumerate(((30.0, (0, -3, 1.5)), (50.0, (3, 0, 1.5)))):
        cam = bpy.data.objects.new(f"sel_{i}", bpy.data.cameras.new(f"sel_{i}"))
        cam.data.lens = lens
        scene.collection.objects.link(cam)
        cam.location = loc
        cam.rotation_euler = (-cam.location).to_track_quat("-Z", "Y").to_euler()
        cam.select_set(True)
        cams.append(cam)
    out = tmp_path / "ds"
    assert bpy.ops.objnerf.export_dataset(directory=str(out), cameras="SELECTED", depth_format="EXR") == {"FINISHED"}
    tf = json.loads((out / "transforms.json").read_text())
    assert len(tf["frames"]) == 2 and "fl_x" not in tf and tf["depth_unit_scale_factor"] == 1.0
    assert [f["fl_x"] for f in tf["frames"]] == pytest.approx([30 / 36 * 64, 50 / 36 * 64])
    assert tf["frames"][0]["depth_file_path"] == "depth/frame_00000.exr"
    depth_m = read_gray(str(out / "depth" / "frame_00000.exr"))
    assert 1 < depth_m.max() < 5  # metres, a few metres away
    # objnerf reads the EXR as metres: its export (millimetres) is the same depth.
    subprocess.run([objnerf_bin, "export", "nerfstudio", str(out), "--out", str(tmp_path / "ns")], check=True,
                   capture_output=True)
    mm = read_depth_png_mm(str(tmp_path / "ns" / "depth" / "frame_00000.png"))
    assert np.abs(mm - depth_m * 1000).max() <= 0.5 + 1e-3 * depth_m.max()
    with pytest.raises(RuntimeError, match="choose an output folder"):
        bpy.ops.objnerf.export_dataset(directory="", cameras="SELECTED")
