"""A stand-in for `objnerf render-edit`, written into a test's folder as an executable: a fixture
for the add-on's subprocess plumbing (arguments, progress, failure, cancel, loading frames back),
NOT a renderer. It writes the documented layout of docs/edit-format.md:

* frame_NNNNN.png: left half red (a "NeRF object" at 2 m), right half green (background, +inf),
  blue = 40 * frame index (so a test can tell which file Blender shows at which frame);
* depth_NNNNN.exr: 2.0 on the left, +inf on the right, one 32-bit float channel named "Y" (as
  documented; written by `write_exr_y` below, not by Blender, so Blender's reading of such a file
  is tested); alpha_ and index_NNNNN.png; camera_path.json.

Every other command (`export nerfstudio`, which importing a COLMAP run needs, `--help`) is passed
on to the real objnerf binary given to `write`, so only render-edit is stood in for.

Modes (environment): STANDIN_FAIL=1 exits 1 with a message on stderr; STANDIN_SLOW=s sleeps s
seconds per frame (for cancelling).
"""

import os
import stat
import struct
import sys

TEMPLATE = '''#!{python}
import json, os, shutil, sys, time
sys.path.insert(0, {addon_dir!r})
sys.path.insert(0, {tests_dir!r})
from standin import write_exr_y
args = sys.argv[1:]
if not args or args[0] != "render-edit":
    os.execv({real!r}, [{real!r}, *args])
edit, opts = args[1], dict(zip(args[2::2], args[3::2]))
if os.environ.get("STANDIN_FAIL"):
    sys.stderr.write("error: " + edit + ": objects[0].model: the model file is missing\\n")
    sys.exit(1)
import numpy as np
from objnerf_blender import formats
json.load(open(edit))
path = json.load(open(opts["--path"]))
w, h = map(int, opts["--size"].split("x"))
# The add-on lets objnerf take a hardware GPU when the machine has one.
assert opts.get("--device") == "auto", opts
assert (w, h) == (path["render_width"], path["render_height"])
out = opts["--out"]
os.makedirs(out, exist_ok=True)
passes = opts.get("--passes", "rgb").split(",")
for k in range(len(path["camera_path"])):
    time.sleep(float(os.environ.get("STANDIN_SLOW", "0.05")))
    rgb = np.zeros((h, w, 3), np.uint8)
    rgb[:, : w // 2] = (255, 0, 40 * k)
    rgb[:, w // 2 :] = (0, 255, 40 * k)
    if "depth" in passes:
        d = np.full((h, w), np.inf, np.float32)
        d[:, : w // 2] = 2.0
        write_exr_y(os.path.join(out, "depth_%05d.exr" % k), d)
    if "alpha" in passes:
        formats.write_png(os.path.join(out, "alpha_%05d.png" % k), np.full((h, w), 255, np.uint8))
    if "index" in passes:
        formats.write_png(os.path.join(out, "index_%05d.png" % k), np.where(np.arange(w) < w // 2, 1, 0).astype(np.uint8)[None].repeat(h, 0))
    formats.write_png(os.path.join(out, "frame_%05d.png" % k), rgb)
shutil.copy(opts["--path"], os.path.join(out, "camera_path.json"))
'''


def write_exr_y(path, depth):
    """An uncompressed scanline OpenEXR with one FLOAT channel "Y" (rows top to bottom)."""
    import numpy as np

    h, w = depth.shape

    def attr(name, kind, value):
        return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value

    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    header = b"".join([
        struct.pack("<ii", 20000630, 2),
        attr("channels", "chlist", b"Y\0" + struct.pack("<iB3xii", 2, 0, 1, 1) + b"\0"),
        attr("compression", "compression", b"\0"),
        attr("dataWindow", "box2i", box),
        attr("displayWindow", "box2i", box),
        attr("lineOrder", "lineOrder", b"\0"),
        attr("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0)),
        attr("screenWindowWidth", "float", struct.pack("<f", 1.0)),
        b"\0",
    ])
    row_bytes = 4 * w
    start = len(header) + 8 * h
    offsets = struct.pack(f"<{h}Q", *[start + y * (8 + row_bytes) for y in range(h)])
    rows = b"".join(struct.pack("<ii", y, row_bytes) + np.asarray(depth[y], "<f4").tobytes() for y in range(h))
    with open(path, "wb") as f:
        f.write(header + offsets + rows)


def write(folder, addon_dir, real):
    """Write the stand-in as `folder/objnerf` (executable) and return its path; commands other
    than render-edit run the `real` objnerf binary."""
    path = os.path.join(folder, "objnerf")
    with open(path, "w") as f:
        f.write(TEMPLATE.format(python=sys.executable, addon_dir=addon_dir,
                                tests_dir=os.path.dirname(os.path.abspath(__file__)), real=real))
    os.chmod(path, os.stat(path).st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
    return path
