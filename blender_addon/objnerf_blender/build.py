"""Blender objects from objnerf's data: the root Empty, cameras, point clouds and proxies.

Children of the root are parented with an identity parent-inverse, so their local matrices are
capture-frame coordinates (see `frames.py`). Proxies get their origin at the model's pivot, so
that the edit file's transform is the proxy's local transform:
`location = pivot + translation`, `rotation_quaternion = rotation`, `scale = (s, s, s)`.
"""

import os

import bpy
import numpy as np
from mathutils import Matrix

from . import compat, formats, frames
from .errors import ObjnerfError
from .props import PIVOT_KEY

POINTS_GROUP = "objnerf points"
COLOUR_ATTR = "Col"


def new_collection(name, parent):
    col = bpy.data.collections.new(name)
    parent.children.link(col)
    return col


def new_root(context, name, capture_to_blender):
    """The run's collection (with cameras / points / proxies sub-collections) and root Empty."""
    top = new_collection(f"objnerf {name}", context.scene.collection)
    subs = {k: new_collection(f"{name} {k}", top) for k in ("cameras", "points", "proxies")}
    # Points and proxies are guides: Blender's renders are composited over objnerf's frames, in
    # which the objects already are.
    subs["points"].hide_render = True
    subs["proxies"].hide_render = True
    root = bpy.data.objects.new(f"objnerf {name}", None)
    root.empty_display_type = "ARROWS"
    root.objnerf.role = "ROOT"
    root.matrix_world = capture_to_blender
    top.objects.link(root)
    return root, subs


def parent_to(obj, root):
    obj.parent = root
    obj.matrix_parent_inverse = Matrix.Identity(4)


# ---------------------------------------------------------------------------------- cameras


def add_cameras(context, root, collection, tf, set_render=True, backgrounds=True):
    """One Blender camera per transforms.json frame. Distortion is noted on the camera as
    custom properties (`objnerf_camera_model`, `objnerf_distortion`), not faked: Blender's
    cameras are pinholes. Returns the camera objects."""
    cams, distorted = [], 0
    centre = np.mean([np.array(f["c2w"])[:3, 3] for f in tf["frames"]], axis=0)
    extent = max(1e-6, max(np.linalg.norm(np.array(f["c2w"])[:3, 3] - centre) for f in tf["frames"]))
    aspect = (1.0, 1.0)
    for fr in tf["frames"]:
        data = bpy.data.cameras.new(fr["name"])
        aspect = frames.apply_intrinsics(data, fr["fx"], fr["fy"], fr["cx"], fr["cy"], fr["w"], fr["h"])
        data.clip_start = extent * 1e-3
        data.clip_end = extent * 100.0
        data.display_size = extent * 0.05
        obj = bpy.data.objects.new(fr["name"], data)
        obj.objnerf.role = "CAMERA"
        obj["objnerf_image"] = fr["image"]
        obj["objnerf_size"] = [fr["w"], fr["h"]]
        obj["objnerf_camera_model"] = fr["camera_model"]
        if fr["distortion"]:
            obj["objnerf_distortion"] = fr["distortion"]
            distorted += 1
        collection.objects.link(obj)
        parent_to(obj, root)
        obj.matrix_basis = Matrix(fr["c2w"])
        if backgrounds and os.path.isfile(fr["image"]):
            img = bpy.data.images.load(fr["image"], check_existing=True)
            bg = data.background_images.new()
            bg.image = img
            data.show_background_images = True
        cams.append(obj)
    if set_render and cams:
        r = context.scene.render
        first = tf["frames"][0]
        r.resolution_x, r.resolution_y, r.resolution_percentage = first["w"], first["h"], 100
        r.pixel_aspect_x, r.pixel_aspect_y = aspect
        context.scene.camera = cams[0]
    return cams, distorted


# ---------------------------------------------------------------------------------- meshes


def _colour_material(name):
    """A material showing the colour attribute (vertex colours) as captured, unlit: emission for
    camera rays and transparent to every other ray, the node setup Blender's own glTF importer
    builds for KHR_materials_unlit (objnerf's .glb default). A radiance field's colour already
    holds the capture's lighting: shaded by the scene's lights it would be lit twice."""
    mat = bpy.data.materials.get(name)
    if mat is not None:
        return mat
    mat = bpy.data.materials.new(name)
    nt = compat.material_nodes(mat)
    out = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    for n in [n for n in nt.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"]:
        nt.nodes.remove(n)
    attr = nt.nodes.new("ShaderNodeAttribute")
    attr.attribute_name = COLOUR_ATTR
    emit = nt.nodes.new("ShaderNodeEmission")
    nt.links.new(attr.outputs["Color"], emit.inputs["Color"])
    path = nt.nodes.new("ShaderNodeLightPath")
    clear = nt.nodes.new("ShaderNodeBsdfTransparent")
    mix = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    nt.links.new(clear.outputs["BSDF"], mix.inputs[1])
    nt.links.new(emit.outputs["Emission"], mix.inputs[2])
    nt.links.new(mix.outputs["Shader"], out.inputs["Surface"])
    return mat


def mesh_from_arrays(name, xyz, rgb=None, faces=()):
    """A mesh from numpy vertices, optional per-vertex colours (sRGB 0..1) and faces."""
    me = bpy.data.meshes.new(name)
    n = len(xyz)
    me.vertices.add(n)
    me.vertices.foreach_set("co", np.asarray(xyz, dtype=np.float32).ravel())
    if len(faces):
        sizes = np.fromiter((len(f) for f in faces), dtype=np.int32, count=len(faces))
        idx = np.concatenate([np.asarray(f, dtype=np.int32) for f in faces])
        if idx.size and (idx.min() < 0 or idx.max() >= n):
            raise ObjnerfError(f"mesh '{name}': a face refers to a vertex that does not exist")
        me.loops.add(idx.size)
        me.loops.foreach_set("vertex_index", idx)
        me.polygons.add(len(faces))
        me.polygons.foreach_set("loop_start", np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int32))
        me.polygons.foreach_set("loop_total", sizes)
    if rgb is not None:
        attr = me.color_attributes.new(COLOUR_ATTR, "BYTE_COLOR", "POINT")
        rgba = np.ones((n, 4), dtype=np.float32)
        rgba[:, :3] = rgb
        attr.data.foreach_set("color_srgb", rgba.ravel())
        me.color_attributes.active_color = attr
    me.update(calc_edges=True)
    me.validate()
    return me


def _points_group():
    """Geometry nodes drawing a vertex-only mesh as points (viewport and render)."""
    ng = bpy.data.node_groups.get(POINTS_GROUP)
    if ng is not None:
        return ng
    ng = bpy.data.node_groups.new(POINTS_GROUP, "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    radius = ng.interface.new_socket("Radius", in_out="INPUT", socket_type="NodeSocketFloat")
    radius.default_value = 0.005
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gin = ng.nodes.new("NodeGroupInput")
    gout = ng.nodes.new("NodeGroupOutput")
    to_points = ng.nodes.new("GeometryNodeMeshToPoints")
    set_mat = ng.nodes.new("GeometryNodeSetMaterial")
    set_mat.inputs["Material"].default_value = _colour_material("objnerf colours")
    ng.links.new(gin.outputs[0], to_points.inputs["Mesh"])
    ng.links.new(gin.outputs[1], to_points.inputs["Radius"])
    ng.links.new(to_points.outputs["Points"], set_mat.inputs["Geometry"])
    ng.links.new(set_mat.outputs["Geometry"], gout.inputs[0])
    return ng


def add_points(name, path, root, collection, radius, transform=None):
    """A point cloud from a PLY file (capture frame, or taken there by the 4x4 `transform`),
    drawn as points of `radius`."""
    xyz, rgb, _ = formats.read_ply(path)
    if transform is not None:
        xyz = xyz @ transform[:3, :3].T + transform[:3, 3]
    obj = bpy.data.objects.new(name, mesh_from_arrays(name, xyz, rgb))
    obj.objnerf.role = "POINTS"
    obj["objnerf_ply"] = path
    mod = obj.modifiers.new("objnerf points", "NODES")
    mod.node_group = _points_group()
    compat.set_modifier_input(mod, "Radius", radius)
    collection.objects.link(obj)
    parent_to(obj, root)
    return obj


def add_proxy(name, model, mesh_ply, root, collection, model_mpu=0.0, source_name=None):
    """An object's mesh (`mesh.ply`, capture frame) as a proxy with its origin at the model's
    pivot (the centre of the field's box, read from the `.objf` header: objnerf's default)."""
    header = formats.read_objf_header(model)
    piv = formats.model_pivot(header)
    xyz, rgb, faces = formats.read_ply(mesh_ply)
    me = mesh_from_arrays(name, xyz - np.array(piv), rgb, faces)
    me.materials.append(_colour_material("objnerf colours"))
    obj = bpy.data.objects.new(name, me)
    p = obj.objnerf
    p.role = "PROXY"
    p.model = os.path.abspath(model)
    p.source_name = source_name or name
    p.model_metres_per_unit = model_mpu
    obj[PIVOT_KEY] = piv
    obj.rotation_mode = "QUATERNION"
    collection.objects.link(obj)
    parent_to(obj, root)
    obj.location = piv
    return obj


def sub_collection(root, kind):
    """The root's cameras / points / proxies collection (made when missing)."""
    top = root.users_collection[0]
    for c in top.children:
        if c.name.endswith(f" {kind}"):
            return c
    c = new_collection(f"{root.name} {kind}", top)
    c.hide_render = kind != "cameras"
    return c
