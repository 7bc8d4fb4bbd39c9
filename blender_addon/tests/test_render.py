"""The render-edit operator's plumbing, against a stand-in executable (tests/standin.py) that writes
render-edit's documented outputs: arguments, progress, loading the frames back as the camera's
background sequence, the compositor's Z combine with a Blender object, failure and cancel."""

import json
import math
import os
import time

import bpy
import numpy as np
import pytest
import standin
from conftest import ADDON_DIR, blender_report, scene_objects
from objnerf_blender import compat, render


def setup_scene(demo_run, n_frames=3):
    """The demo run imported, a still scene camera looking along +y from the origin, and
    Blender's own objects: a wall at 3 m (green-ish) and a white cube at 1 m, left of centre."""
    bpy.ops.objnerf.import_run(directory=os.path.join(demo_run, "run"), backgrounds=False)
    scene = bpy.context.scene
    cam = bpy.data.objects.new("shot", bpy.data.cameras.new("shot"))
    scene.collection.objects.link(cam)
    cam.rotation_euler = (math.radians(90), 0, 0)
    scene.camera = cam
    scene.frame_start, scene.frame_end = 1, n_frames
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 64, 48, 100
    r.engine = "BLENDER_WORKBENCH"
    sh = scene.display.shading
    sh.light, sh.color_type = "FLAT", "OBJECT"
    bpy.ops.mesh.primitive_plane_add(size=40, location=(0, 3, 0), rotation=(math.radians(90), 0, 0))
    bpy.context.active_object.color = (0.0, 0.2, 1.0, 1.0)
    bpy.ops.mesh.primitive_cube_add(size=0.1, location=(-0.2, 1.0, 0))  # columns ~10-18
    bpy.context.active_object.color = (1.0, 1.0, 1.0, 1.0)
    return cam


def render_composite(path):
    scene = bpy.context.scene
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(path)
    img.colorspace_settings.name = "Non-Color"
    w, h = img.size
    a = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(a)
    return np.rint(a.reshape(h, w, 4)[::-1, :, :3] * 255).astype(int)


def test_render_edit_with_stand_in_composites_by_depth(prefs, demo_run, tmp_path):
    prefs.binary = standin.write(str(tmp_path), ADDON_DIR, prefs.binary)
    cam = setup_scene(demo_run)
    work = tmp_path / "work"
    assert bpy.ops.objnerf.render_edit(directory=str(work)) == {"FINISHED"}
    out = work / "render"
    assert sorted(os.listdir(out))[:3] == ["alpha_00000.png", "alpha_00001.png", "alpha_00002.png"]
    assert len(render._frames(str(out))) == 3 and (out / "camera_path.json").is_file()
    edit = json.loads((work / "edit.json").read_text())
    assert edit["objects"][0]["name"] == "mug"
    # The camera shows the frames as a background sequence.
    bg = [b for b in cam.data.background_images if b.image and b.image.name.startswith("objnerf")]
    assert len(bg) == 1 and bg[0].image.source == "SEQUENCE" and bg[0].image_user.frame_duration == 3
    # The composite: ours (left, 2 m) over the wall (3 m); the cube (1 m) over ours; the wall over
    # our background (+inf) on the right. Blue tells which file was shown: 40 x (frame - 1).
    for frame in (1, 3):
        bpy.context.scene.frame_set(frame)
        px = render_composite(str(tmp_path / f"comp_{frame}.png"))
        k = frame - 1
        for col in (3, 26):
            assert np.abs(px[24, col] - (255, 0, 40 * k)).max() <= 2, px[24, col]  # ours, left
        assert np.abs(px[24, 58] - px[5, 58]).max() <= 2 and px[24, 58][2] > 200  # the wall, right
        assert (px[24, 58][0], px[24, 58][1]) == (0, px[24, 58][1]) and px[24, 58][1] < 200
        cube = px[24, 14]
        assert (cube >= 250).all(), cube  # the cube, in front of ours
    print("composite: ours over the wall, the cube over ours, the wall over our background")


def test_load_render_operator_reads_a_folder(prefs, demo_run, tmp_path):
    prefs.binary = standin.write(str(tmp_path), ADDON_DIR, prefs.binary)
    setup_scene(demo_run, n_frames=2)
    render.start_job(bpy.context, scene_objects("ROOT")[0], str(tmp_path / "w"))[0].wait()
    assert bpy.ops.objnerf.load_render(directory=str(tmp_path / "w" / "render")) == {"FINISHED"}
    names = {n.name for n in compat.compositor_tree(bpy.context.scene, create=False).nodes}
    assert {"objnerf z combine", "objnerf frames", "objnerf depth"} <= names
    with blender_report("no frame_00000.png"):
        bpy.ops.objnerf.load_render(directory=str(tmp_path))


def test_failing_render_reports_its_stderr(prefs, demo_run, tmp_path, monkeypatch):
    prefs.binary = standin.write(str(tmp_path), ADDON_DIR, prefs.binary)
    setup_scene(demo_run)
    monkeypatch.setenv("STANDIN_FAIL", "1")
    with blender_report(r"render-edit' failed \(exit 1\): error: .*the model file is missing"):
        bpy.ops.objnerf.render_edit(directory=str(tmp_path / "w"))


def test_invoke_without_a_window_runs_to_the_end(prefs, demo_run, tmp_path):
    """In background mode there is no window for a modal timer: invoke falls back to execute."""
    prefs.binary = standin.write(str(tmp_path), ADDON_DIR, prefs.binary)
    setup_scene(demo_run, n_frames=2)
    assert bpy.ops.objnerf.render_edit("INVOKE_DEFAULT", directory=str(tmp_path / "w")) == {"FINISHED"}


def test_modal_session_on_timer_events(prefs, demo_run, tmp_path):
    """What the modal operator does per event, driven here without Blender's event loop."""
    prefs.binary = standin.write(str(tmp_path), ADDON_DIR, prefs.binary)
    setup_scene(demo_run, n_frames=3)
    session = render.RenderSession(bpy.context, scene_objects("ROOT")[0], str(tmp_path / "w"))
    assert session.tick(bpy.context, "MOUSEMOVE") == "PASS"
    states = []
    deadline = time.monotonic() + 120
    while (not states or states[-1] == "RUNNING") and time.monotonic() < deadline:
        states.append(session.tick(bpy.context, "TIMER"))
        time.sleep(0.1)
    assert states[-1] == "FINISHED" and "RUNNING" in states and session.frames == 3


def test_cancel_stops_the_render(prefs, demo_run, tmp_path, monkeypatch):
    prefs.binary = standin.write(str(tmp_path), ADDON_DIR, prefs.binary)
    setup_scene(demo_run, n_frames=4)
    monkeypatch.setenv("STANDIN_SLOW", "1.0")
    session = render.RenderSession(bpy.context, scene_objects("ROOT")[0], str(tmp_path / "w"))
    job = session.job
    assert job.total == 4 and job.progress() == 0.0
    deadline = time.monotonic() + 60
    while job.progress() == 0.0 and time.monotonic() < deadline:
        assert session.tick(bpy.context, "TIMER") == "RUNNING"
        time.sleep(0.1)
    assert 0.0 < job.progress() < 1.0, "the stand-in wrote no frame within 60 s"
    assert session.tick(bpy.context, "ESC") == "CANCELLED"
    assert job.poll() is not None  # the process is gone
    with pytest.raises(Exception, match="cancelled"):
        job.finish()


def test_render_without_binary_is_a_report(addon, demo_run, objnerf_bin, tmp_path):
    p = bpy.context.preferences.addons["objnerf_blender"].preferences
    p.binary = objnerf_bin  # importing a COLMAP run needs the binary (export nerfstudio)
    setup_scene(demo_run, n_frames=1)
    p.binary = str(tmp_path / "missing" / "objnerf")
    with blender_report("objnerf binary not found"):
        bpy.ops.objnerf.render_edit(directory=str(tmp_path / "w"))
