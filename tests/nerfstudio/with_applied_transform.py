"""A copy of a nerfstudio transforms.json with absolute file paths and nerfstudio's COLMAP
applied_transform (x <-> y, z negated, as ns-process-data writes it): a dataset whose frame
nerfstudio reaches from an original one, so that camera paths must undo it. Plain Python (json,
os): the Blender add-on's tests import it too.

Usage: python with_applied_transform.py TRANSFORMS_JSON OUT_DIR   (writes OUT_DIR/transforms.json)
"""

import json
import os
import sys

COLMAP_APPLIED = [[0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0]]


def with_applied_transform(transforms_json, out_dir):
    with open(transforms_json, encoding="utf-8") as f:
        doc = json.load(f)
    base = os.path.dirname(os.path.abspath(transforms_json))
    for owner in (doc, *doc["frames"]):
        for key in ("file_path", "depth_file_path", "mask_path", "ply_file_path"):
            if key in owner:
                owner[key] = os.path.join(base, owner[key])
    doc["applied_transform"] = COLMAP_APPLIED
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, "transforms.json")
    with open(path + ".tmp", "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=2)
    os.replace(path + ".tmp", path)
    return path


if __name__ == "__main__":
    print(with_applied_transform(sys.argv[1], sys.argv[2]))
