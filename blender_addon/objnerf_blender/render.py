"""Render the edit with `objnerf render-edit` and bring the frames back into Blender.

The operator writes `edit.json` and `camera_path.json` (the scene camera's animation) into its
folder, runs `objnerf render-edit edit.json --path camera_path.json --out render/ --size WxH
--passes rgb,alpha,depth,index` in the background (progress = frames written / frames asked,
in the status bar; Esc cancels), then:

* loads `render/frame_NNNNN.png` as the camera's background image sequence (viewport), and
* builds a compositor graph that puts Blender's own objects over objnerf's frames with a
  Z combine of the two depth passes, so a Blender object can stand among the NeRF objects.

Depth: objnerf's pass is z-depth in metres (+inf where nothing was hit), Blender's is z-depth in
its world units, which are the capture's units times the root's scale; objnerf's depth is scaled
by root scale / metres_per_unit and capped at 1e9 so that where Blender drew nothing (its Z is
1e10) our frame, background included, shows.
"""

import glob
import os
import time

import bpy
from bpy.props import StringProperty

from . import camera_path, cli, compat, edit, prefs, props
from .errors import ObjnerfError, reports_errors

PASSES = "rgb,alpha,depth,index"
NODE_PREFIX = "objnerf "
FAR = 1e9


def _frames(out_dir, kind="frame", ext="png"):
    return sorted(glob.glob(os.path.join(out_dir, f"{kind}_[0-9][0-9][0-9][0-9][0-9].{ext}")))


def prepare(context, root, base_dir, passes=PASSES):
    """Write the edit and the camera path into `base_dir`; returns (args, out_dir, frame count)."""
    base_dir = os.path.abspath(bpy.path.abspath(base_dir))
    os.makedirs(base_dir, exist_ok=True)
    edit_path = os.path.join(base_dir, "edit.json")
    path_path = os.path.join(base_dir, "camera_path.json")
    edit.write_edit(context, root, edit_path)
    doc = camera_path.write_camera_path(context, context.scene.camera, root, path_path)
    out_dir = os.path.join(base_dir, "render")
    # A previous render's frames would count as progress and be loaded back: remove only those.
    for kind, ext in (("frame", "png"), ("alpha", "png"), ("depth", "exr"), ("index", "png")):
        for f in _frames(out_dir, kind, ext):
            os.remove(f)
    args = ["render-edit", edit_path, "--path", path_path, "--out", out_dir,
            "--size", f"{doc['render_width']}x{doc['render_height']}", "--passes", passes,
            # A hardware GPU when the machine has one (the CPU otherwise; the report says which).
            "--device", "auto"]
    return args, out_dir, len(doc["camera_path"])


def start_job(context, root, base_dir, passes=PASSES):
    binary = prefs.binary(context)
    args, out_dir, n = prepare(context, root, base_dir, passes)
    os.makedirs(out_dir, exist_ok=True)
    return cli.BackgroundJob(binary, args, os.path.dirname(out_dir), n, lambda: len(_frames(out_dir)),
                             prefs.models_dir(context)), out_dir


# ------------------------------------------------------------------------------ loading back


def _sequence(path, name, non_colour=False):
    img = bpy.data.images.load(path, check_existing=False)
    img.name = name
    img.source = "SEQUENCE"
    if non_colour:
        img.colorspace_settings.name = "Non-Color"
    return img


def _set_sequence_user(user, scene, n):
    """Frame k of the render (file number k, from 0) shows at scene frame frame_start + k."""
    user.frame_start = scene.frame_start
    user.frame_duration = n
    user.frame_offset = -1  # Blender shows file number (frame - frame_start + 1) + offset
    user.use_auto_refresh = True


def load_render(context, root, out_dir, cam=None):
    """Background image sequence on the camera and the compositor graph; returns the frame count."""
    scene = context.scene
    cam = cam or scene.camera
    rgb = _frames(out_dir)
    if not rgb:
        raise ObjnerfError(f"{out_dir} has no frame_00000.png: nothing to load")
    n = len(rgb)
    # Viewport: the frames behind the camera's view.
    for bg in list(cam.data.background_images):
        if bg.image is not None and bg.image.name.startswith(NODE_PREFIX):
            cam.data.background_images.remove(bg)
    frames_img = _sequence(rgb[0], NODE_PREFIX + "frames")
    bg = cam.data.background_images.new()
    bg.image = frames_img
    _set_sequence_user(bg.image_user, scene, n)
    bg.alpha = 1.0
    cam.data.show_background_images = True
    depth = _frames(out_dir, "depth", "exr")
    if len(depth) != n:
        raise ObjnerfError(f"{out_dir} has {n} frames but {len(depth)} depth passes: render with --passes depth")
    build_compositor(scene, frames_img, _sequence(depth[0], NODE_PREFIX + "depth", non_colour=True), n,
                     root.matrix_world.to_scale()[0] / root.objnerf.metres_per_unit)
    return n


def build_compositor(scene, frames_img, depth_img, n, depth_factor):
    """objnerf's frames and Blender's render, Z-combined, into the render result."""
    scene.view_layers[0].use_pass_z = True
    # Our PNGs are display-referred sRGB: the Standard view transform gives them back unchanged
    # (Filmic/AgX would tone-map them a second time).
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    nt = compat.compositor_tree(scene)
    for node in list(nt.nodes):
        if node.name.startswith(NODE_PREFIX):
            nt.nodes.remove(node)

    def named(nd, name, x, y):
        nd.name = nd.label = NODE_PREFIX + name
        nd.location = (x, y)
        return nd

    def node(kind, name, x, y):
        return named(nt.nodes.new(kind), name, x, y)

    ours = node("CompositorNodeImage", "frames", -600, 300)
    ours.image = frames_img
    ours_z = node("CompositorNodeImage", "depth", -600, 0)
    ours_z.image = depth_img
    for nd in (ours, ours_z):
        _set_sequence_user(nd, scene, n)
    split = node("CompositorNodeSeparateColor", "depth channel", -400, 0)
    scale = node(compat.MATH_NODE, "depth to Blender units", -200, 0)
    scale.operation = "MULTIPLY"
    scale.inputs[1].default_value = depth_factor
    cap = node(compat.MATH_NODE, "depth cap", 0, 0)
    cap.operation = "MINIMUM"
    cap.inputs[1].default_value = FAR
    layers = node("CompositorNodeRLayers", "render layers", -600, -300)
    layers.scene = scene
    zc = named(compat.zcombine(nt, use_alpha=False, antialias=True), "z combine", 200, 100)
    link = nt.links.new
    link(ours_z.outputs["Image"], split.inputs[0])
    link(split.outputs[0], scale.inputs[0])
    link(scale.outputs[0], cap.inputs[0])
    link(ours.outputs["Image"], zc.inputs[0])
    link(cap.outputs[0], zc.inputs[1])
    link(layers.outputs["Image"], zc.inputs[2])
    link(layers.outputs["Depth"], zc.inputs[3])
    link(zc.outputs[0], compat.composite_input(nt))


# -------------------------------------------------------------------------------- operators


def _status(context, text):
    ws = context.workspace
    if ws is not None:
        ws.status_text_set(text)


class RenderSession:
    """One render-edit run driven by events: what the modal operator does on each timer tick or
    key, without Blender's event loop, so that it can be driven (and tested) from scripts too.
    `tick` returns "RUNNING", "FINISHED" (frames loaded back), "CANCELLED" or "PASS" (not ours)."""

    def __init__(self, context, root, directory):
        self.root = root
        self.job, self.out = start_job(context, root, directory)
        self.frames = 0

    def tick(self, context, event_type):
        if event_type == "ESC":
            self.job.cancel()
            return "CANCELLED"
        if event_type != "TIMER":
            return "PASS"
        done = self.job.progress()
        context.window_manager.progress_update(int(done * 100))
        _status(context, f"objnerf render-edit: {round(done * self.job.total)}/{self.job.total} frames (Esc to cancel)")
        if self.job.poll() is None:
            return "RUNNING"
        self.job.finish()  # raises with the render's stderr when it failed
        self.frames = load_render(context, self.root, self.out)
        return "FINISHED"


class OBJNERF_OT_render_edit(bpy.types.Operator):
    """Render the edit along the active camera's animation with objnerf render-edit, then
    composite the frames with Blender's own objects (Esc cancels)"""

    bl_idname = "objnerf.render_edit"
    bl_label = "Render edit"

    directory: StringProperty(name="Folder", subtype="DIR_PATH", default="//objnerf_render/",
                              description="Where edit.json, camera_path.json and render/ go")

    _session = None
    _timer = None

    def _done(self):
        s = self._session
        self.report({"INFO"}, f"rendered {s.frames} frames into {s.out}; composited with the Z pass")
        return {"FINISHED"}

    @reports_errors
    def execute(self, context):
        """Blocking (scripts, background mode: no timer events there)."""
        self._session = RenderSession(context, props.active_root(context), self.directory)
        while self._session.tick(context, "TIMER") == "RUNNING":
            time.sleep(0.2)
        return self._done()

    @reports_errors
    def invoke(self, context, event):
        if context.window is None:
            return self.execute(context)
        self._session = RenderSession(context, props.active_root(context), self.directory)
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.25, window=context.window)
        wm.modal_handler_add(self)
        wm.progress_begin(0, 100)
        _status(context, "objnerf render-edit: starting (Esc to cancel)")
        return {"RUNNING_MODAL"}

    def _stop(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        _status(context, None)

    @reports_errors
    def modal(self, context, event):
        try:
            state = self._session.tick(context, event.type)
        except BaseException:
            # Whatever went wrong, the timer, the progress and the subprocess go with it.
            self._session.job.cancel()
            self._stop(context)
            raise
        if state == "PASS":
            return {"PASS_THROUGH"}
        if state == "RUNNING":
            return {"RUNNING_MODAL"}
        self._stop(context)
        if state == "CANCELLED":
            self.report({"WARNING"}, "objnerf render-edit cancelled")
            return {"CANCELLED"}
        return self._done()

    def cancel(self, context):
        """Blender calls this when the operator is stopped from outside (file load, quit)."""
        if self._session is not None:
            self._session.job.cancel()
        self._stop(context)


class OBJNERF_OT_load_render(bpy.types.Operator):
    """Load a render-edit output folder as the camera's background and the compositor graph"""

    bl_idname = "objnerf.load_render"
    bl_label = "Load render-edit frames"

    directory: StringProperty(name="Folder", subtype="DIR_PATH", description="render-edit's --out folder")

    @reports_errors
    def execute(self, context):
        n = load_render(context, props.active_root(context), bpy.path.abspath(self.directory))
        self.report({"INFO"}, f"loaded {n} frames")
        return {"FINISHED"}

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}


CLASSES = (OBJNERF_OT_render_edit, OBJNERF_OT_load_render)
