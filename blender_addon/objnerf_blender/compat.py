"""What differs between the Blender versions the add-on supports: 4.5 LTS and 5.x (tested on 5.2
LTS). Every version check lives here; the rest of the add-on has one code path.

* The compositor: 4.5 edits the scene's own `scene.node_tree` (after `scene.use_nodes = True`)
  and ends in a Composite node; 5.0 removed both: the scene points at a compositor node group
  (`scene.compositing_node_group`), whose Group Output is the render result. 5.0 also dropped
  the compositor's own Math node for the shared `ShaderNodeMath`, and rebuilt the File Output
  node (`directory`, `file_output_items` of a socket type, each item's `override_node_format`,
  and a format with a `media_type`, instead of `base_path` and `file_slots`).
* Materials always have nodes in 5.x (`Material.use_nodes` is deprecated).
* Geometry Nodes modifier inputs: 4.5 stores them as ID properties on the modifier
  (`mod[identifier] = value`); 5.2 refuses that ("id properties not supported for this type") and
  has `mod.properties.inputs.<identifier>.value`. Told apart by the attribute, since it is not
  the 5.0 change.
"""

import bpy

from .errors import ObjnerfError

# The oldest Blender the add-on runs on (also blender_version_min in blender_manifest.toml, which
# a test keeps equal). Older: register() refuses with this message rather than failing later.
MIN_VERSION = (4, 5, 0)
BLENDER_5 = bpy.app.version >= (5, 0, 0)


def require_supported(version=None):
    """ObjnerfError naming both versions when Blender is older than MIN_VERSION."""
    version = tuple(version or bpy.app.version)
    if version[:3] < MIN_VERSION:
        have = ".".join(map(str, version[:3]))
        need = ".".join(map(str, MIN_VERSION))
        raise ObjnerfError(f"objnerf needs Blender {need} or newer (4.5 LTS, 5.x); this is Blender {have}")


# ------------------------------------------------------------------------- geometry nodes


def set_modifier_input(mod, name, value):
    """Set the Geometry Nodes modifier's input `name` (the group interface's socket name)."""
    identifier = mod.node_group.interface.items_tree[name].identifier
    props = getattr(mod, "properties", None)
    if props is not None:  # 5.2
        getattr(props.inputs, identifier).value = value
    else:
        mod[identifier] = value


def modifier_input(mod, name):
    identifier = mod.node_group.interface.items_tree[name].identifier
    props = getattr(mod, "properties", None)
    return getattr(props.inputs, identifier).value if props is not None else mod[identifier]


# -------------------------------------------------------------------------------- materials


def material_nodes(mat):
    """The material's shader node tree (a new material has Principled BSDF and an output): 4.5
    makes it on `use_nodes = True`; 5.x always has one and deprecates `use_nodes`."""
    if not BLENDER_5:
        mat.use_nodes = True
    return mat.node_tree


# ------------------------------------------------------------------------------ compositor

COMPOSITOR_GROUP = "objnerf compositor"
MATH_NODE = "ShaderNodeMath" if BLENDER_5 else "CompositorNodeMath"


def compositor_tree(scene, create=True):
    """The scene's compositor node tree, made (and compositing turned on) when `create`; None
    when there is none and `create` is False."""
    if not BLENDER_5:
        if create:
            scene.use_nodes = True
        return scene.node_tree
    nt = scene.compositing_node_group
    if nt is None and create:
        nt = bpy.data.node_groups.new(COMPOSITOR_GROUP, "CompositorNodeTree")
        scene.compositing_node_group = nt
    return nt


def use_compositor(scene, set_attr):
    """The scene's compositor tree for one export, switched on through `set_attr(obj, attr,
    value)` (which remembers and restores): 4.5's use_nodes, or in 5.x a new group when the scene
    has none (`drop_unused_compositor` removes it again after the restore)."""
    if not BLENDER_5:
        set_attr(scene, "use_nodes", True)
        return scene.node_tree
    if scene.compositing_node_group is None:
        set_attr(scene, "compositing_node_group", bpy.data.node_groups.new(COMPOSITOR_GROUP, "CompositorNodeTree"))
    return scene.compositing_node_group


def drop_unused_compositor(nt):
    """Remove a compositor group `use_compositor` made, once nothing uses it (5.x)."""
    if nt is not None and BLENDER_5 and nt.users == 0:
        bpy.data.node_groups.remove(nt)


def composite_input(nt):
    """The socket whose image is the render result: the Composite node's (4.5) or the group
    output's first (5.x), made when missing."""
    if not BLENDER_5:
        comp = next((nd for nd in nt.nodes if nd.bl_idname == "CompositorNodeComposite"), None)
        if comp is None:
            comp = nt.nodes.new("CompositorNodeComposite")
        return comp.inputs["Image"]
    if not any(it.item_type == "SOCKET" and it.in_out == "OUTPUT" for it in nt.interface.items_tree):
        nt.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    out = next((nd for nd in nt.nodes if nd.bl_idname == "NodeGroupOutput" and nd.is_active_output), None)
    if out is None:
        out = nt.nodes.new("NodeGroupOutput")
        out.location = (400, 100)
    return out.inputs[0]


def _set_exr(fmt, colour_mode):
    if BLENDER_5:
        fmt.media_type = "IMAGE"  # a File Output node starts as multilayer EXR in 5.x
    fmt.file_format, fmt.color_depth, fmt.color_mode = "OPEN_EXR", "32", colour_mode


def file_output_exr(nt, directory, slots):
    """A File Output node writing one single-layer 32-bit EXR per slot into `directory`;
    `slots` is [(file name prefix, "RGBA" or "BW")]. Returns (node, input sockets in slot order).
    Files are named prefix + frame number (4.5) or prefix alone (5.x): glob `prefix*.exr`."""
    out = nt.nodes.new("CompositorNodeOutputFile")
    if BLENDER_5:
        out.directory, out.file_name = directory, ""
        _set_exr(out.format, "RGBA")
        for prefix, mode in slots:
            item = out.file_output_items.new("RGBA" if mode == "RGBA" else "FLOAT", prefix)
            item.override_node_format = True
            _set_exr(item.format, mode)
    else:
        out.base_path = directory
        _set_exr(out.format, "RGBA")
        for i, (prefix, mode) in enumerate(slots):
            if i == 0:
                out.file_slots[0].path = prefix
            else:
                out.file_slots.new(prefix)  # returns the node's new input socket, not the slot
            slot = out.file_slots[i]
            slot.use_node_format = False
            _set_exr(slot.format, mode)
    return out, [out.inputs[i] for i in range(len(slots))]


def zcombine(nt, use_alpha, antialias):
    """A Z Combine node: inputs 0-3 are (image A, depth A, image B, depth B) and output 0 the
    image in both versions; the options are input sockets (4.5 has the properties too)."""
    zc = nt.nodes.new("CompositorNodeZcombine")
    zc.inputs["Use Alpha"].default_value = use_alpha
    zc.inputs["Anti-Alias"].default_value = antialias
    return zc
