"""The add-on registers and unregisters cleanly (File > Import entries included), the extension zip
installs in Blender, and a Blender older than the supported range is refused with a clear message."""

import json
import os
import subprocess
import sys
import zipfile

import addon_utils
import bpy
from conftest import MODULE, ROOT, scene_objects
from objnerf_blender import compat, ui

OPERATORS = ["import_run", "import_scene", "duplicate", "set_visible", "set_recolour", "insert_object",
             "export_edit", "export_camera_path", "render_edit", "load_render", "export_dataset"]


def registered():
    return {
        "panel": hasattr(bpy.types, "OBJNERF_PT_panel"),
        "prefs": MODULE in bpy.context.preferences.addons
        and bpy.context.preferences.addons[MODULE].preferences is not None,
        "props": hasattr(bpy.types.Object, "objnerf"),
        "ops": [op for op in OPERATORS if hasattr(bpy.types, f"OBJNERF_OT_{op}")],
        "import_menu": ui.draw_import_menu in import_menu_funcs(),
    }


def import_menu_funcs():
    """The draw functions File > Import shows (Menu.append's list; none appended yet: empty)."""
    return getattr(bpy.types.TOPBAR_MT_file_import.draw, "_draw_funcs", [])


def test_register_unregister_cleanly():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    for _ in range(2):  # twice: unregistering must leave nothing that breaks registering again
        assert addon_utils.enable(MODULE, default_set=True, handle_error=None) is not None
        r = registered()
        assert r["panel"] and r["prefs"] and r["props"] and r["ops"] == OPERATORS and r["import_menu"], r
        addon_utils.disable(MODULE, default_set=True, handle_error=None)
        r = registered()
        assert not r["panel"] and not r["prefs"] and not r["props"] and not r["ops"] and not r["import_menu"], r
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


def test_file_import_menu_runs_the_importers(prefs, demo_run):
    """File > Import lists the run and scene importers; the run entry, given report.json as the
    file browser gives it, imports the demo run."""
    assert ui.draw_import_menu in import_menu_funcs()
    assert [getattr(bpy.types, "OBJNERF_OT_" + op.split(".")[1], None) is not None for op, _ in ui.IMPORT_MENU] == \
        [True, True]
    report = os.path.join(demo_run, "run", "report.json")
    assert bpy.ops.objnerf.import_run(filepath=report) == {"FINISHED"}
    assert len(scene_objects("CAMERA")) == 36 and {o.name for o in scene_objects("PROXY")} == {"mug"}


def test_manifest_range_holds_this_blender_and_the_checked_minimum():
    manifest = open(os.path.join(ROOT, "blender_addon", "objnerf_blender", "blender_manifest.toml")).read()

    def version(key):
        line = next(ln for ln in manifest.splitlines() if ln.startswith(key + " "))
        return tuple(int(v) for v in line.split('"')[1].split("."))

    assert version("blender_version_min") == compat.MIN_VERSION
    assert compat.MIN_VERSION <= bpy.app.version < version("blender_version_max")


def test_older_blender_is_refused_with_a_clear_message(monkeypatch):
    """Enabled from a folder on an older Blender, register() stops before registering anything,
    with a message naming both versions (the running Blender stands in, with the minimum raised)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    errors = []
    monkeypatch.setattr(compat, "MIN_VERSION", (bpy.app.version[0] + 1, 0, 0))
    mod = addon_utils.enable(MODULE, default_set=True, handle_error=errors.append)
    have = ".".join(map(str, bpy.app.version))
    assert mod is None and len(errors) == 1
    assert str(errors[0]) == (f"objnerf needs Blender {bpy.app.version[0] + 1}.0.0 or newer (4.5 LTS, 5.x); "
                              f"this is Blender {have}")
    r = registered()
    assert not r["panel"] and not r["props"] and not r["ops"] and not r["import_menu"], r
    monkeypatch.undo()
    assert addon_utils.enable(MODULE, default_set=True, handle_error=None) is not None
    addon_utils.disable(MODULE, default_set=True, handle_error=None)


REFUSE = """
import bpy, sys
bpy.ops.extensions.package_install_files(filepath=sys.argv[1], repo="user_default")
"""


def test_extension_installer_refuses_an_older_blender(tmp_path):
    """The extension zip with blender_version_min above the running Blender: Blender's installer
    says why and installs nothing (how a Blender older than 4.5 meets the real zip)."""
    src = os.path.join(ROOT, "blender_addon", "objnerf_blender")
    zip_path = str(tmp_path / "old.zip")
    with zipfile.ZipFile(zip_path, "w") as z:
        for f in sorted(os.listdir(src)):
            if f.endswith(".py") or f == "blender_manifest.toml":
                text = open(os.path.join(src, f)).read()
                if f == "blender_manifest.toml":
                    text = text.replace(f'blender_version_min = "{".".join(map(str, compat.MIN_VERSION))}"',
                                        f'blender_version_min = "{bpy.app.version[0] + 1}.0.0"')
                    assert f'"{bpy.app.version[0] + 1}.0.0"' in text
                z.writestr(f, text)
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"))
    p = subprocess.run([sys.executable, "-c", REFUSE, zip_path], env=env, capture_output=True, text=True, timeout=300)
    out = p.stdout + p.stderr
    assert f"doesn't meet the minimum supported version ({bpy.app.version[0] + 1}.0.0)" in out, out[-2000:]
    user = tmp_path / "user"
    assert not list(user.rglob("blender_manifest.toml")), list(user.rglob("*"))
