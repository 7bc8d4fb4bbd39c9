"""The textured mesh of an `extract` run in Blender: `RUN/<object>/mesh.glb` through Blender's own
glTF importer keeps its image texture and its unlit material (KHR_materials_unlit) and stands at
the origin at the stated scale; the add-on's own proxies show their colours unlit too."""

import json
import os

import bpy
import numpy as np
from conftest import scene_objects
from objnerf_blender import formats


def node_kinds(mat):
    return {n.bl_idname for n in mat.node_tree.nodes}


def surface_shader(mat):
    out = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    return out.inputs["Surface"].links[0].from_node


def test_textured_glb_imports_unlit_with_its_texture_at_its_scale(demo_run):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    run = os.path.join(demo_run, "run")
    with open(os.path.join(run, "report.json")) as f:
        o = json.load(f)["objects"][0]
    assert bpy.ops.import_scene.gltf(filepath=os.path.join(run, o["name"], "mesh.glb")) == {"FINISHED"}
    obj = next(x for x in bpy.data.objects if x.type == "MESH")
    assert len(obj.data.polygons) == o["export"]["triangles"]
    assert len(obj.data.uv_layers) == 1
    mat = obj.data.materials[0]
    kinds = node_kinds(mat)
    # Blender's importer builds KHR_materials_unlit as emission for camera rays.
    assert {"ShaderNodeEmission", "ShaderNodeLightPath"} <= kinds, kinds
    assert "ShaderNodeBsdfPrincipled" not in kinds, kinds
    assert surface_shader(mat).bl_idname == "ShaderNodeMixShader"
    tex = [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage"]
    size = o["export"]["atlas"]["size"]
    assert len(tex) == 1 and tuple(tex[0].image.size) == (size, size)
    assert tex[0].image.colorspace_settings.name == "sRGB"
    # Origin at the base (Blender is Z up): standing on z = 0, centred on x = y = 0, as tall as
    # the full mesh (capture frame, Z up for the demo) times the stated scale, to a voxel.
    frame = o["frame"]
    assert frame["origin"] == "base"
    bb = np.array([obj.matrix_world @ v.co for v in obj.data.vertices])
    lo, hi = bb.min(axis=0), bb.max(axis=0)
    assert abs(lo[2]) < 1e-4, lo
    assert np.allclose((lo[:2] + hi[:2]) / 2, 0.0, atol=1e-4), (lo, hi)
    xyz, _, _ = formats.read_ply(os.path.join(run, o["name"], "mesh.ply"))
    voxel = o["train"]["setup"]["voxel"]
    full_height = float(xyz[:, 2].max() - xyz[:, 2].min()) * frame["scale"]
    print(f"height in Blender {hi[2] - lo[2]:.4f}, full mesh {full_height:.4f}, voxel {voxel:.4f}")
    assert abs((hi[2] - lo[2]) - full_height) < voxel * frame["scale"]


def test_proxies_show_their_colours_unlit(prefs, demo_run):
    assert bpy.ops.objnerf.import_run(directory=os.path.join(demo_run, "run")) == {"FINISHED"}
    proxy = scene_objects("PROXY")[0]
    mat = proxy.data.materials[0]
    assert "ShaderNodeEmission" in node_kinds(mat)
    assert "ShaderNodeBsdfPrincipled" not in node_kinds(mat)
    assert surface_shader(mat).bl_idname == "ShaderNodeMixShader"
