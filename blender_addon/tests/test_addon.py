"""The add-on registers and unregisters cleanly, and the extension zip installs in Blender."""

import json
import os
import subprocess
import sys

import addon_utils
import bpy
from conftest import MODULE, ROOT

OPERATORS = ["import_run", "import_scene", "duplicate", "set_visible", "set_recolour", "insert_object",
             "export_edit", "export_camera_path", "render_edit", "load_render", "export_dataset"]


def registered():
    return {
        "panel": hasattr(bpy.types, "OBJNERF_PT_panel"),
        "prefs": MODULE in bpy.context.preferences.addons
        and bpy.context.preferences.addons[MODULE].preferences is not None,
        "props": hasattr(bpy.types.Object, "objnerf"),
        "ops": [op for op in OPERATORS if hasattr(bpy.types, f"OBJNERF_OT_{op}")],
    }


def test_register_unregister_cleanly():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    for _ in range(2):  # twice: unregistering must leave nothing that breaks registering again
        assert addon_utils.enable(MODULE, default_set=True, handle_error=None) is not None
        r = registered()
        assert r["panel"] and r["prefs"] and r["props"] and r["ops"] == OPERATORS, r
        addon_utils.disable(MODULE, default_set=True, handle_error=None)
        r = registered()
        assert not r["panel"] and not r["prefs"] and not r["props"] and not r["ops"], r
        assert MODULE not in bpy.context.preferences.addons


def test_every_operator_is_listed_and_called_in_a_test():
    """The add-on's operators are exactly OPERATORS, and each is called (`bpy.ops.objnerf.NAME(`)
    in some test of this folder: a new operator without a test fails here."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon_utils.enable(MODULE, default_set=True, handle_error=None)
    try:
        found = sorted(n[len("OBJNERF_OT_"):] for n in dir(bpy.types) if n.startswith("OBJNERF_OT_"))
    finally:
        addon_utils.disable(MODULE, default_set=True, handle_error=None)
    assert found == sorted(OPERATORS), found
    here = os.path.dirname(os.path.abspath(__file__))
    tests = "".join(open(os.path.join(here, f)).read() for f in os.listdir(here)
                    if f.startswith("test_") and f.endswith(".py"))
    uncalled = [op for op in OPERATORS if f"bpy.ops.objnerf.{op}(" not in tests]
    assert not uncalled, f"operators no test calls: {uncalled}"


INSTALL = """
import bpy, addon_utils, json, sys
bpy.ops.extensions.package_install_files(filepath=sys.argv[1], repo="user_default")
mod = addon_utils.enable("bl_ext.user_default.objnerf_blender", default_set=True, handle_error=None)
prefs = bpy.context.preferences.addons["bl_ext.user_default.objnerf_blender"].preferences
print("RESULT" + json.dumps({"module": mod.__name__, "file": mod.__file__,
                             "has_ops": hasattr(bpy.types, "OBJNERF_OT_render_edit"),
                             "prefs_binary": prefs.binary}))
"""


def test_extension_zip_installs_and_enables(tmp_path):
    """scripts/build-blender-addon's zip, installed with Blender's extension installer (which
    checks the manifest) into a throwaway user folder, enables as bl_ext.user_default.*."""
    out = subprocess.run(["bash", os.path.join(ROOT, "scripts", "build-blender-addon")], check=True,
                         capture_output=True, text=True).stdout.strip().splitlines()[-1]
    zip_path = os.path.join(ROOT, out)
    assert os.path.isfile(zip_path), out
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"))
    p = subprocess.run([sys.executable, "-c", INSTALL, zip_path], env=env, capture_output=True, text=True, timeout=300)
    line = next((ln for ln in p.stdout.splitlines() if ln.startswith("RESULT")), None)
    assert line, p.stdout[-2000:] + p.stderr[-2000:]
    r = json.loads(line[len("RESULT"):])
    assert r["module"] == "bl_ext.user_default.objnerf_blender" and r["has_ops"] and r["prefs_binary"] == ""
    assert r["file"].startswith(str(tmp_path / "user"))
