"""End to end with the real renderer: a camera path authored in bpy (a keyframed 24-frame orbit) and
an edit (the mug moved 0.15 and turned 90 degrees, the torus recoloured), rendered by
`objnerf render-edit`, loaded back; in every frame the object-index pass of the moved mug and
Blender's own render of the moved proxy from the same camera agree (silhouette IoU >= 0.9). This
is the test that the conventions (frames, pivot, camera path, image rows) agree end to end.

Skipped, with the reason printed, while `objnerf render-edit --help` fails (issue 16).
"""

import json
import math
import os
import shutil
import subprocess

import bpy
import numpy as np
import pytest
from conftest import CACHE, scene_objects, skip
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Quaternion, Vector
from objnerf_blender import camera_path, cli
from test_camera_path import orbit_camera
from test_dataset import read_gray

SIZE = (160, 120)


@pytest.fixture(scope="module")
def two_object_run(objnerf_bin, demo_run):
    """An extract run of the demo scene with the mug and the torus (clicks from the scene's truth)."""
    if not cli.has_command(objnerf_bin, "render-edit"):
        skip("objnerf render-edit does not exist yet (`objnerf render-edit --help` fails): issue 16")
    out = os.path.join(CACHE, "demo_mug_torus")
    if not os.path.isfile(os.path.join(out, "report.json")):
        scene = os.path.join(demo_run, "scene")
        truth = json.load(open(os.path.join(scene, "truth", "objects.json")))["objects"]
        args = [objnerf_bin, "extract", scene, "--view", "view_000.png"]
        for o in truth:
            if o["name"] in ("mug", "torus"):
                args += ["--object", o["name"], "--point", "{},{}".format(*o["click"])]
        shutil.rmtree(out, ignore_errors=True)
        subprocess.run(["nice", "-n", "10", *args, "--time-budget", "60", "--out", out], check=True,
                       stdout=subprocess.DEVNULL)
    return out


def silhouette_of(obj, path):
    """Blender's own render of one proxy (Workbench, transparent film), alpha > 0.5."""
    scene = bpy.context.scene
    keep = {o.name: o.hide_render for o in scene.objects}
    cols = {c.name: c.hide_render for c in bpy.data.collections}
    try:
        for c in bpy.data.collections:
            c.hide_render = False
        for o in scene.objects:
            o.hide_render = o is not obj
        r = scene.render
        r.engine, r.film_transparent, r.use_compositing = "BLENDER_WORKBENCH", True, False
        r.image_settings.color_mode = "RGBA"
        r.filepath = path
        bpy.ops.render.render(write_still=True)
    finally:
        for o in scene.objects:
            o.hide_render = keep[o.name]
        for c in bpy.data.collections:
            c.hide_render = cols[c.name]
    img = bpy.data.images.load(path)
    w, h = img.size
    a = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(a)
    bpy.data.images.remove(img)
    return a.reshape(h, w, 4)[::-1, :, 3] > 0.5


def test_orbit_edit_render_edit_and_back(prefs, two_object_run, tmp_path):
    bpy.ops.objnerf.import_run(directory=two_object_run, backgrounds=False)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = SIZE
    mug, torus = bpy.data.objects["mug"], bpy.data.objects["torus"]
    mug.location = Vector(mug.location) + Vector((0.15, 0.0, 0.0))
    mug.rotation_quaternion = Quaternion((0, 0, 1), math.radians(90))
    torus.objnerf.recolour_mode = "TARGET"
    torus.objnerf.recolour_target = (0.125, 0.314, 1.0)
    orbit_camera(n=24, radius=2.2, height=1.1, lens=(35.0, 35.0))
    # A Blender object standing among the NeRF objects, for the composite.
    bpy.ops.mesh.primitive_cone_add(radius1=0.12, depth=0.35, location=(0.1, -0.35, 0.175))
    work = tmp_path / "work"
    assert bpy.ops.objnerf.render_edit(directory=str(work)) == {"FINISHED"}
    out = work / "render"
    edit = json.loads((work / "edit.json").read_text())
    mug_index = [o["name"] for o in edit["objects"]].index("mug") + 1
    # objnerf read our camera path back: the path it rendered along is ours.
    ours, theirs = (camera_path.read_camera_path(str(p)) for p in (work / "camera_path.json", out / "camera_path.json"))
    assert len(ours) == len(theirs) == 24
    for a, b in zip(ours, theirs):
        assert np.abs(a["c2w"] - b["c2w"]).max() < 1e-6 and abs(a["fx"] - b["fx"]) < 1e-6 * a["fx"]
    ious = []
    for k in range(24):
        scene.frame_set(scene.frame_start + k)
        index = np.rint(read_gray(str(out / f"index_{k:05d}.png")) * 255).astype(int)
        theirs = index == mug_index
        mine = silhouette_of(mug, str(tmp_path / f"mug_{k:05d}.png"))
        ious.append((theirs & mine).sum() / max(1, (theirs | mine).sum()))
    print(f"render-edit index pass vs Blender's proxy silhouette: min IoU {min(ious):.3f}, mean {np.mean(ious):.3f}")
    assert min(ious) >= 0.9
    scene.frame_set(scene.frame_start + 6)
    r = scene.render
    r.engine, r.use_compositing, r.film_transparent = "BLENDER_WORKBENCH", True, False
    r.image_settings.color_mode = "RGB"
    r.filepath = str(tmp_path / "composite.png")
    bpy.ops.render.render(write_still=True)
    print(f"composite frame (NeRF objects and a Blender cone): {tmp_path / 'composite.png'}")
    # The cone stands in front of objnerf's empty background (+inf depth there), so the
    # composite shows Blender's grey cone where it projects, and objnerf's white around it.
    img = bpy.data.images.load(r.filepath)
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    px = px.reshape(h, w, 4)[::-1, :, :3]
    cone = bpy.data.objects["Cone"]
    u, v, _ = world_to_camera_view(scene, scene.camera, cone.matrix_world @ Vector((0, 0, -0.05)))
    cx, cy = int(u * w), int((1 - v) * h)
    print(f"composite at the cone ({cx}, {cy}): {px[cy, cx]}, a corner: {px[2, 2]}")
    assert px[cy, cx].max() < 0.9 and px[2, 2].min() > 0.95
    assert scene_objects("ROOT")
