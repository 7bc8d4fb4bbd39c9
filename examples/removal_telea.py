"""The per-view 2D inpainting baseline for object removal: OpenCV's Telea (`cv2.inpaint`) on each
view's own photo, over the same region a removal leaves out (the segmentation's masks grown by
DILATE pixels, a square neighbourhood as objnerf's `util::mask::dilate`), scored against the demo
scene's truth of the removal.

python removal_telea.py SCENE_DIR SEGMENT_DIR --objects mug[,torus] --views view_003.png,...
    [--dilate 4] [--score-dilate 4] [--radius 3] [--out-images DIR]

Prints one JSON object: per view and in all, the squared error and pixel count over the whole
frame and inside each object's true mask grown by SCORE_DILATE pixels (so PSNRs pool pixels the
way objnerf's removal report does), and the seconds cv2.inpaint took.
"""

import argparse
import json
import os
import sys
import time

import cv2
import numpy as np

ORDER = ["mug", "sphere", "box", "torus"]  # the demo's object order (truth/removed/<a>+<b>)


def read(path, flags=cv2.IMREAD_COLOR):
    img = cv2.imread(path, flags)
    if img is None:
        sys.exit(f"error: {path}: cannot read")
    return img


def grow(mask, r):
    """Square dilation by r pixels of a 0/1 mask."""
    return cv2.dilate(mask, np.ones((2 * r + 1, 2 * r + 1), np.uint8)) if r > 0 else mask


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("segment")
    ap.add_argument("--objects", required=True)
    ap.add_argument("--views", required=True)
    ap.add_argument("--dilate", type=int, default=4)
    ap.add_argument("--score-dilate", type=int, default=4)
    ap.add_argument("--radius", type=float, default=3.0)
    ap.add_argument("--out-images")
    a = ap.parse_args()
    objects = a.objects.split(",")
    truth_dir = os.path.join(a.scene, "truth", "removed", "+".join(sorted(objects, key=ORDER.index)))
    views = []
    total = {"sse": 0.0, "n": 0, "inside": {o: {"sse": 0.0, "n": 0} for o in objects}, "seconds": 0.0}
    for v in a.views.split(","):
        img = read(os.path.join(a.scene, "images", v))
        removed = np.zeros(img.shape[:2], np.uint8)
        for o in objects:
            m = os.path.join(a.segment, "masks", o, os.path.splitext(v)[0] + ".png")
            if os.path.isfile(m):
                removed |= (read(m, cv2.IMREAD_GRAYSCALE) > 127).astype(np.uint8)
        hole = grow(removed, a.dilate)
        t = time.perf_counter()
        filled = cv2.inpaint(img, hole * 255, a.radius, cv2.INPAINT_TELEA)
        secs = time.perf_counter() - t
        if a.out_images:
            os.makedirs(a.out_images, exist_ok=True)
            cv2.imwrite(os.path.join(a.out_images, v), filled)
        truth = read(os.path.join(truth_dir, v)).astype(np.float64) / 255.0
        err = ((filled.astype(np.float64) / 255.0 - truth) ** 2).sum(axis=2)
        rec = {"view": v, "sse": float(err.sum()) / 3.0, "n": int(err.size), "inside": {}, "seconds": secs}
        for o in objects:
            tm = read(os.path.join(a.scene, "truth", "masks", o, v), cv2.IMREAD_GRAYSCALE) > 127
            inside = grow(tm.astype(np.uint8), a.score_dilate).astype(bool)
            rec["inside"][o] = {"sse": float(err[inside].sum()) / 3.0, "n": int(inside.sum())}
            total["inside"][o]["sse"] += rec["inside"][o]["sse"]
            total["inside"][o]["n"] += rec["inside"][o]["n"]
        total["sse"] += rec["sse"]
        total["n"] += rec["n"]
        total["seconds"] += secs
        views.append(rec)

    def psnr(sse, n):
        return float(-10.0 * np.log10(max(sse / max(n, 1), 1e-12)))

    out = {
        "method": "telea",
        "views": views,
        "psnr_frame_mean": float(np.mean([psnr(r["sse"], r["n"]) for r in views])),
        "psnr_inside": {o: psnr(s["sse"], s["n"]) for o, s in total["inside"].items()},
        "seconds": total["seconds"],
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
