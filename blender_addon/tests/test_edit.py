"""Authoring edits on proxies and exporting edit.json: every object's transform in the file, applied
by the formula of docs/edit-format.md to the model's mesh, lands where Blender draws the proxy."""

import json
import math
import os

import bpy
import numpy as np
import pytest
from conftest import scene_objects
from mathutils import Quaternion, Vector
from objnerf_blender import formats


def apply_edit(entry, file_mpu, p):
    """docs/edit-format.md: p is drawn at k pivot + translation + scale k R (p - pivot)."""
    k = entry.get("metres_per_unit", file_mpu) / file_mpu
    piv = np.array(entry["pivot"])
    q = entry["rotation"]
    r = np.array(Quaternion((q["w"], q["x"], q["y"], q["z"])).normalized().to_matrix(), dtype=np.float64)
    return k * piv + np.array(entry["translation"]) + entry["scale"] * k * (p - piv) @ r.T


def drawn(obj, root):
    """Where Blender draws the proxy's vertices, in the capture frame."""
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    m = np.array(root.matrix_world.inverted() @ obj.matrix_world, dtype=np.float64)
    return np.c_[co.reshape(-1, 3), np.ones(len(co) // 3)] @ m.T[:, :3]


def select(*objs):
    for o in bpy.context.selected_objects:
        o.select_set(False)
    for o in objs:
        o.select_set(True)
    bpy.context.view_layer.objects.active = objs[-1]


def test_edit_operators_and_export(prefs, demo_run, tmp_path):
    run = os.path.join(demo_run, "run")
    bpy.ops.objnerf.import_run(directory=run, backgrounds=False)
    root = scene_objects("ROOT")[0]
    mug = bpy.data.objects["mug"]
    # Move 0.15 along x and turn 90 degrees about z, as in the composite-render issue.
    mug.location = Vector(mug.location) + Vector((0.15, 0.0, 0.0))
    mug.rotation_quaternion = Quaternion((0, 0, 1), math.radians(90))
    select(mug)
    assert bpy.ops.objnerf.duplicate() == {"FINISHED"}
    dup = bpy.context.active_object
    assert dup is not mug and dup.objnerf.role == "PROXY" and dup.data is mug.data
    dup.scale = (1.5, 1.5, 1.5)
    assert bpy.ops.objnerf.set_visible(visible=False) == {"FINISHED"}
    assert not dup.objnerf.visible and dup.display_type == "WIRE"
    select(mug)
    assert bpy.ops.objnerf.set_recolour(mode="TARGET", target=(0.125, 0.3137, 1.0), strength=0.8) == {"FINISHED"}
    bpy.context.scene.cursor.location = (0.3, -0.2, 0.05)
    assert bpy.ops.objnerf.insert_object(directory=run, object_name="mug", model_metres_per_unit=0.25) == {"FINISHED"}
    ins = bpy.context.active_object
    assert np.allclose(ins.location, (0.3, -0.2, 0.05), atol=1e-6) and np.allclose(ins.scale, 0.25)
    ins.rotation_quaternion = Quaternion((1, 0, 0), math.radians(30))
    select(ins)
    bpy.ops.objnerf.set_recolour(mode="HUE", hue_degrees=-45.0, strength=0.5)

    out = tmp_path / "edits" / "edit.json"
    assert bpy.ops.objnerf.export_edit(filepath=str(out)) == {"FINISHED"}
    doc = json.loads(out.read_text())
    assert doc["version"] == 1 and doc["metres_per_unit"] == 1.0
    assert doc["background"] == {"color": "#ffffff"}
    by_name = {e["name"]: e for e in doc["objects"]}
    assert set(by_name) == {mug.name, dup.name, ins.name}
    assert by_name[mug.name]["recolour"] == {"target": "#2050ff", "strength": 0.8}
    assert by_name[mug.name]["visible"] and not by_name[dup.name]["visible"]
    assert by_name[ins.name]["metres_per_unit"] == 0.25
    assert by_name[ins.name]["recolour"] == {"hue_degrees": -45.0, "strength": 0.5}
    assert np.allclose(by_name[mug.name]["translation"], (0.15, 0, 0), atol=1e-6)
    assert np.allclose(by_name[dup.name]["scale"], 1.5) and np.allclose(by_name[ins.name]["scale"], 1.0)
    q = by_name[mug.name]["rotation"]
    assert np.allclose([q["w"], q["z"]], [math.sqrt(0.5)] * 2, atol=1e-6)
    mesh_xyz, _, _ = formats.read_ply(os.path.join(run, "mug", "mesh.ply"))
    for obj in (mug, dup, ins):
        e = by_name[obj.name]
        assert os.path.normpath(os.path.join(out.parent, e["model"])) == os.path.join(run, "mug", "model.objf")
        err = np.abs(apply_edit(e, doc["metres_per_unit"], mesh_xyz) - drawn(obj, root)).max()
        print(f"{obj.name}: edit.json transform vs Blender's proxy, max {err:.2e}")
        assert err < 1e-5


def test_edit_export_refuses_what_the_file_cannot_say(prefs, demo_run, tmp_path):
    bpy.ops.objnerf.import_run(directory=os.path.join(demo_run, "run"), backgrounds=False)
    mug = bpy.data.objects["mug"]
    mug.scale = (1.0, 2.0, 1.0)
    with pytest.raises(RuntimeError, match="non-uniform scale"):
        bpy.ops.objnerf.export_edit(filepath=str(tmp_path / "edit.json"))
    mug.scale = (1.0, 1.0, 1.0)
    root = scene_objects("ROOT")[0]
    root.objnerf.background_mode = "MODEL"
    with pytest.raises(RuntimeError, match="no model file"):
        bpy.ops.objnerf.export_edit(filepath=str(tmp_path / "edit.json"))
    root.objnerf.background_model = os.path.join(demo_run, "run", "mug", "model.objf")
    assert bpy.ops.objnerf.export_edit(filepath=str(tmp_path / "edit.json")) == {"FINISHED"}
    doc = json.loads((tmp_path / "edit.json").read_text())
    assert os.path.isabs(doc["background"]["model"]) is False
    assert not (tmp_path / "edit.json.tmp").exists()
    for o in bpy.context.selected_objects:
        o.select_set(False)
    with pytest.raises(RuntimeError, match="select one or more objnerf proxies"):
        bpy.ops.objnerf.duplicate()
