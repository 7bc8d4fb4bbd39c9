"""Held-out PSNR of an object field's renders, over the whole frame and over the mask's padded box,
as rendered (the identity appearance) and after each view's best affine colour map (3 x 4, least
squares: how per-image-appearance methods such as NeRF-W are scored on views no training fixed).

    objnerf render MODEL --scene SCENE --out RENDERS
    python examples/appearance_score.py RENDERS IMAGES MASKS --downscale 4 --hold-out-every 6

IMAGES: the scene's photos; MASKS: the object's masks named like them (an extract run's
segment/masks/OBJECT). The truth is the photo premultiplied by the mask, box-downscaled,
composited on white, as `objnerf eval` makes it. Needs numpy and OpenCV (cv2).
"""

import argparse
import json
import os

import cv2
import numpy as np


def box_down(a, f):
    h, w = a.shape[0] // f * f, a.shape[1] // f * f
    a = a[:h, :w]
    return a.reshape(h // f, f, w // f, f, *a.shape[2:]).mean(axis=(1, 3))


def psnr(a, b):
    return -10 * np.log10(max(np.mean((a - b) ** 2), 1e-20))


def colour_fit(r, t):
    x = np.concatenate([r.reshape(-1, 3), np.ones((r.size // 3, 1))], axis=1)
    m, *_ = np.linalg.lstsq(x, t.reshape(-1, 3), rcond=None)
    return (x @ m).reshape(t.shape)


def padded_box(alpha):
    ys, xs = np.nonzero(alpha >= 0.5)
    if len(xs) == 0:
        return None
    x0, x1, y0, y1 = xs.min(), xs.max() + 1, ys.min(), ys.max() + 1
    px, py = int(np.ceil((x1 - x0) * 0.1)) + 1, int(np.ceil((y1 - y0) * 0.1)) + 1
    h, w = alpha.shape
    return max(y0 - py, 0), min(y1 + py, h), max(x0 - px, 0), min(x1 + px, w)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("renders")
    ap.add_argument("images")
    ap.add_argument("masks")
    ap.add_argument("--downscale", type=int, default=4)
    ap.add_argument("--hold-out-every", type=int, default=6)
    a = ap.parse_args()
    names = sorted(f for f in os.listdir(a.images) if f.lower().endswith((".jpg", ".png")))
    n = a.hold_out_every
    held = [v for i, v in enumerate(names) if i % n == n // 2]
    rows = []
    for v in held:
        stem = os.path.splitext(v)[0]
        photo = cv2.imread(os.path.join(a.images, v))[:, :, ::-1] / 255.0
        mask = cv2.imread(os.path.join(a.masks, stem + ".png"), cv2.IMREAD_GRAYSCALE) / 255.0
        alpha = box_down(mask, a.downscale)
        truth = box_down(photo * mask[:, :, None], a.downscale) + (1 - alpha[:, :, None])
        render = cv2.imread(os.path.join(a.renders, stem + ".png"))[:, :, ::-1] / 255.0
        render = render[: truth.shape[0], : truth.shape[1]]
        y0, y1, x0, x1 = padded_box(alpha)
        rb, tb = render[y0:y1, x0:x1], truth[y0:y1, x0:x1]
        rows.append(
            {
                "view": v,
                "frame": psnr(render, truth),
                "frame_fit": psnr(colour_fit(render, truth), truth),
                "box": psnr(rb, tb),
                "box_fit": psnr(colour_fit(rb, tb), tb),
            }
        )
    mean = {k: float(np.mean([r[k] for r in rows])) for k in rows[0] if k != "view"}
    print(json.dumps({"views": len(rows), "mean": mean, "per_view": rows}))


if __name__ == "__main__":
    main()
