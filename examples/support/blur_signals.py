"""Can a capture's motion blur be told from its images alone? (issue 54, the stability suite's
blur_7 case). For each folder of photos, each view as it is and blurred along a random direction
over 3 and 7 pixels (the suite's own blur: the mean of L samples along a line), three measures:

  fine/coarse  the share of gradient energy along the view's weakest direction at full
               resolution over the same share at a quarter of it (motion blur removes fine
               detail along one direction; content's own anisotropy is there at both scales)
  lap ratio    the Laplacian's energy at full resolution over that at half resolution
  acf min      the most negative autocorrelation of the directional derivative at lags 4-15
               (a box blur of length L leaves a negative lobe at lag L along its direction)

Usage: python examples/support/blur_signals.py NAME=FOLDER [NAME=FOLDER ...]
(numpy and Pillow; images are scaled to at most 480 px on their long side; seed 0.)
"""
import glob
import math
import sys

import numpy as np
from PIL import Image

rng = np.random.default_rng(0)


def gray(a):
    return a[..., :3] @ [0.299, 0.587, 0.114]


def motion_blur(a, length, angle):
    h, w = a.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w]
    acc = np.zeros_like(a)
    for k in range(length):
        t = k - (length - 1) / 2
        sx = np.clip(np.round(xs + t * math.cos(angle)), 0, w - 1).astype(int)
        sy = np.clip(np.round(ys + t * math.sin(angle)), 0, h - 1).astype(int)
        acc += a[sy, sx]
    return acc / length


def gradients(g):
    return (g[1:-1, 2:] - g[1:-1, :-2]) / 2, (g[2:, 1:-1] - g[:-2, 1:-1]) / 2


def tensor(g):
    gx, gy = gradients(g)
    j = np.array([[np.sum(gx * gx), np.sum(gx * gy)], [np.sum(gx * gy), np.sum(gy * gy)]])
    return j / gx.size


def down(g, k):
    h, w = g.shape
    return g[: h // k * k, : w // k * k].reshape(h // k, k, w // k, k).mean((1, 3))


def fine_over_coarse(g):
    j1, j4 = tensor(g), tensor(down(g, 4))
    ev, vecs = np.linalg.eigh(j1)
    v = vecs[:, 0]
    return (ev[0] / np.trace(j1)) / ((v @ j4 @ v) / np.trace(j4))


def laplacian_ratio(g):
    def lap(x):
        return x[1:-1, 2:] + x[1:-1, :-2] + x[2:, 1:-1] + x[:-2, 1:-1] - 4 * x[1:-1, 1:-1]

    return np.mean(lap(g) ** 2) / np.mean(lap(down(g, 2)) ** 2)


def acf_min(g, lags=range(4, 16), directions=16):
    gx, gy = gradients(g)
    h, w = gx.shape
    best = 0.0
    for k in range(directions):
        c, s = math.cos(math.pi * k / directions), math.sin(math.pi * k / directions)
        d = c * gx + s * gy
        d = d - d.mean()
        var = np.mean(d * d)
        for lag in lags:
            ox, oy = int(round(lag * c)), int(round(lag * s))
            a = d[max(0, -oy) : h - max(0, oy), max(0, -ox) : w - max(0, ox)]
            b = d[max(0, oy) : h + min(0, oy), max(0, ox) : w + min(0, ox)]
            best = min(best, np.mean(a * b) / var)
    return best


def main():
    measures = [("fine/coarse", fine_over_coarse), ("lap ratio", laplacian_ratio), ("acf min", acf_min)]
    print("| capture | views | blur | " + " | ".join(f"{m} min / median / max" for m, _ in measures) + " |")
    print("|---|---|---|" + "---|" * len(measures))
    for arg in sys.argv[1:]:
        name, folder = arg.split("=", 1)
        files = sorted(f for f in glob.glob(folder + "/*") if f.lower().endswith((".png", ".jpg", ".jpeg")))[:8]
        rows = {0: [], 3: [], 7: []}
        for f in files:
            im = Image.open(f).convert("RGB")
            scale = 480 / max(im.size)
            if scale < 1:
                im = im.resize((round(im.size[0] * scale), round(im.size[1] * scale)), Image.BILINEAR)
            a = np.asarray(im).astype(np.float64)
            for length in rows:
                b = a if length == 0 else motion_blur(a, length, rng.uniform(0, math.pi))
                g = gray(b)
                rows[length].append([m(g) for _, m in measures])
        for length, vals in rows.items():
            v = np.array(vals)
            cells = [f"{v[:, i].min():.2f} / {np.median(v[:, i]):.2f} / {v[:, i].max():.2f}" for i in range(len(measures))]
            print(f"| {name} | {len(files)} | {length} px | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
