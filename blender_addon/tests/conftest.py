"""Fixtures for the add-on's tests, which run in real Blender: `bpy` 4.5 and 5.2 from PyPI, each
in its own venv (scripts/test-blender runs them in both).

* `addon`: a fresh empty Blender session with the add-on enabled through Blender's add-on
  system (so preferences exist), disabled again afterwards.
* `objnerf_bin`: the objnerf binary ($OBJNERF_BIN, else the repo's target/release/objnerf, else
  PATH); tests that need it skip with a printed reason when there is none.
* `demo_run`: `objnerf demo`'s output ($OBJNERF_DEMO_RUN, else made once, 2-3 minutes, into
  target/blender-tests/demo and reused by later test runs).
"""

import contextlib
import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ADDON_DIR = os.path.join(ROOT, "blender_addon")
sys.path.insert(0, ADDON_DIR)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bpy  # noqa: E402
import addon_utils  # noqa: E402  (Blender's own module, importable once bpy is loaded)

MODULE = "objnerf_blender"
CACHE = os.path.join(ROOT, "target", "blender-tests")


def skip(reason):
    """Skip with the reason printed (pytest -rs shows it too)."""
    print(f"SKIP: {reason}")
    pytest.skip(reason)


def find_objnerf():
    for cand in (os.environ.get("OBJNERF_BIN"), os.path.join(ROOT, "target", "release", "objnerf"),
                 shutil.which("objnerf")):
        if cand and os.path.isfile(cand) and os.access(cand, os.X_OK):
            return os.path.abspath(cand)
    return None


@pytest.fixture
def addon():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    mod = addon_utils.enable(MODULE, default_set=True, handle_error=None)
    assert mod is not None, "the add-on failed to enable (see the traceback above)"
    yield mod
    addon_utils.disable(MODULE, default_set=True, handle_error=None)


@pytest.fixture(scope="session")
def objnerf_bin():
    b = find_objnerf()
    if b is None:
        skip("no objnerf binary (build it: cargo build --release, or set OBJNERF_BIN)")
    return b


@pytest.fixture
def prefs(addon, objnerf_bin):
    """The add-on's preferences, pointing at the objnerf binary under test."""
    p = bpy.context.preferences.addons[MODULE].preferences
    p.binary = objnerf_bin
    return p


@pytest.fixture(scope="session")
def demo_run(objnerf_bin):
    given = os.environ.get("OBJNERF_DEMO_RUN")
    if given:
        if not os.path.isfile(os.path.join(given, "run", "report.json")):
            pytest.fail(f"OBJNERF_DEMO_RUN={given} has no run/report.json")
        return given
    out = os.path.join(CACHE, "demo")
    if not os.path.isfile(os.path.join(out, "run", "report.json")):
        os.makedirs(CACHE, exist_ok=True)
        print(f"making the demo run in {out} (objnerf demo, 2-3 minutes)")
        subprocess.run([objnerf_bin, "demo", "--out", out], check=True, stdout=subprocess.DEVNULL)
    return out


def scene_objects(role):
    return [o for o in bpy.context.scene.objects if o.objnerf.role == role]


@contextlib.contextmanager
def blender_report(match):
    """The operator inside fails with a Blender error report matching `match` (bpy.ops raises
    RuntimeError("Error: ...")), not with a Python traceback or an unexpected exception."""
    with pytest.raises(RuntimeError, match=match) as e:
        yield
    msg = str(e.value)
    assert msg.startswith("Error: ") and "Traceback" not in msg and "unexpected" not in msg, msg
