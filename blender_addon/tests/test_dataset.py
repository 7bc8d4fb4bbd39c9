"""A Blender scene exported as a nerfstudio dataset: the truth is exact (depth and masks agree with
the known geometry through the exported cameras), objnerf reads it, and objnerf's one-click
segmentation (after `objnerf sfm`) matches the Blender mask pass."""

import json
import os
import subprocess

import addon_utils
import bpy
import numpy as np
import pytest
from conftest import MODULE, scene_objects
from objnerf_blender import formats

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
    mat.use_nodes = True
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


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
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
        ring = scene_objects("NONE")
        assert len([o for o in ring if o.type == "CAMERA"]) == 24
    finally:
        addon_utils.disable(MODULE, default_set=True, handle_error=None)
    return out


def test_dataset_truth_is_exact(dataset):
    tf = formats.read_transforms(os.path.join(dataset, "transforms.json"))
    objs = json.load(open(os.path.join(dataset, "objects.json")))["objects"]
    assert [o["name"] for o in objs] == ["Cube", "Ground", "Sphere", "Torus"]
    assert len(tf["frames"]) == 24 and (tf["frames"][0]["w"], tf["frames"][0]["h"]) == SIZE
    centre, r = np.array(SPHERE["location"]), SPHERE["radius"]
    worst = 0.0
    for fr in tf["frames"]:
        stem = fr["name"]
        depth = read_gray(os.path.join(dataset, "depth", stem + ".exr"))
        mask = read_gray(os.path.join(dataset, "masks", "Sphere", stem + ".png")) > 0.5
        assert mask.sum() > 500
        # Every sphere pixel, back-projected with its depth through the exported camera, lies on
        # the sphere: masks, depth (z, metres), intrinsics and pose all agree.
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
    assert worst < 0.01 * r  # the UV sphere's facets are within 0.1% of r


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


def test_selected_cameras_with_their_own_lenses(addon, tmp_path):
    """Selected cameras (two lenses: intrinsics per frame), PNG depth in millimetres."""
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
    assert bpy.ops.objnerf.export_dataset(directory=str(out), cameras="SELECTED", depth_format="PNG") == {"FINISHED"}
    tf = json.loads((out / "transforms.json").read_text())
    assert len(tf["frames"]) == 2 and "fl_x" not in tf
    assert [f["fl_x"] for f in tf["frames"]] == pytest.approx([30 / 36 * 64, 50 / 36 * 64])
    assert tf["frames"][0]["depth_file_path"] == "depth/frame_00000.png"
    depth_mm = read_gray(str(out / "depth" / "frame_00000.png")) * 65535
    assert 1000 < depth_mm.max() < 5000  # millimetres, a few metres away
    with pytest.raises(RuntimeError, match="choose an output folder"):
        bpy.ops.objnerf.export_dataset(directory="", cameras="SELECTED")
