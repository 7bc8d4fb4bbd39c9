#!/usr/bin/env python3
"""Pictures of what the stability suite's object-PSNR floor looks like (docs/floors.md).

The floor is measured over the true mask's box grown by 10% a side, the object composited on
white, in views the field never trained on. This script takes a view of the demo scene's mug,
composites it on white as the suite's truth does, and degrades it (Gaussian blur, or a shift of
the object by whole pixels, the two ways a field goes wrong) until that PSNR hits each level;
then writes one strip per kind of damage: the truth, then the levels left to right.

    python3 scripts/floor-pictures.py SCENE_DIR VIEW OUT_DIR   (numpy + pillow)

SCENE_DIR: `objnerf demo-scene --out SCENE_DIR` (images/ and truth/masks/mug/).
"""
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageFilter

LEVELS = [24.0, 20.0, 18.0, 16.0, 14.0]
PAD = 0.1


def psnr(a, b):
    mse = float(np.mean((a - b) ** 2))
    return 10 * np.log10(1.0 / max(mse, 1e-12))


def on_white(scene, view):
    rgb = np.asarray(Image.open(scene / "images" / view).convert("RGB"), np.float64) / 255
    m = np.asarray(Image.open(scene / "truth/masks/mug" / view).convert("L"), np.float64) / 255
    ys, xs = np.nonzero(m > 0.5)
    x0, x1, y0, y1 = xs.min(), xs.max() + 1, ys.min(), ys.max() + 1
    px, py = int(round((x1 - x0) * PAD)), int(round((y1 - y0) * PAD))
    h, w = m.shape
    box = (max(x0 - px, 0), max(y0 - py, 0), min(x1 + px, w), min(y1 + py, h))
    img = rgb * m[..., None] + (1 - m[..., None])
    return img, box


def crop(img, box):
    x0, y0, x1, y1 = box
    return img[y0:y1, x0:x1]


def blurred(img, r):
    im = Image.fromarray((img * 255).round().astype(np.uint8))
    return np.asarray(im.filter(ImageFilter.GaussianBlur(r)), np.float64) / 255


def shifted(img, d):
    # The object moved by d pixels (fractional: linear between whole shifts), white comes in.
    k = int(np.floor(d))
    f = d - k

    def sh(n):
        out = np.ones_like(img)
        out[:, n:] = img[:, : img.shape[1] - n] if n > 0 else img
        return out

    return (1 - f) * sh(k) + f * sh(k + 1)


def at_level(truth, box, damage, level, hi):
    lo = 0.0
    for _ in range(40):
        mid = (lo + hi) / 2
        if psnr(crop(damage(truth, mid), box), crop(truth, box)) > level:
            lo = mid
        else:
            hi = mid
    return crop(damage(truth, (lo + hi) / 2), box), (lo + hi) / 2


def main():
    scene, view, out = Path(sys.argv[1]), sys.argv[2], Path(sys.argv[3])
    out.mkdir(parents=True, exist_ok=True)
    truth, box = on_white(scene, view)
    t = crop(truth, box)
    scale = max(1, 160 // t.shape[0])
    for name, damage, hi in [("blur", blurred, 30.0), ("shift", shifted, 40.0)]:
        tiles, notes = [t], []
        for level in LEVELS:
            tile, amount = at_level(truth, box, damage, level, hi)
            tiles.append(tile)
            notes.append(f"{level:.0f} dB: {name} {amount:.2f} px")
        gap = np.ones((t.shape[0], 4, 3))
        strip = np.concatenate([x for tile in tiles for x in (tile, gap)][:-1], axis=1)
        im = Image.fromarray((strip * 255).round().astype(np.uint8))
        im = im.resize((im.width * scale, im.height * scale), Image.NEAREST)
        path = out / f"floor_{name}.png"
        im.save(path)
        print(path, "; ".join(notes))


if __name__ == "__main__":
    main()
