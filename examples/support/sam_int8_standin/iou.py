# mask IoU of candidate encoders against the fp32 encoder (same decoder), on demo/lego/fox views
import sys, os, json, numpy as np, onnxruntime as ort
from PIL import Image
sys.path.insert(0, "/tmp/sam58/py"); from common import prep
FP32 = "/root/.cache/objnerf/models/mobile_sam/encoder.onnx"; DEC = "/root/.cache/objnerf/models/mobile_sam/decoder.onnx"
def opts():
    o = ort.SessionOptions(); o.intra_op_num_threads = 2; return o
dec = ort.InferenceSession(sys.argv[2] if len(sys.argv) > 2 and sys.argv[2].endswith("dec.onnx") else DEC, opts())
def interior(m):
    ys, xs = np.nonzero(m); cy, cx = ys.mean(), xs.mean(); i = np.argmin((ys-cy)**2 + (xs-cx)**2); return float(xs[i]), float(ys[i])
cases = []  # (name, path, [(x,y)])
D = "/tmp/sam58/demo"
for v in [0, 6, 12, 18, 24, 30]:
    p = f"{D}/images/view_{v:03d}.png"; pts = []
    for o in ["mug","sphere","box","torus"]:
        m = np.asarray(Image.open(f"{D}/truth/masks/{o}/view_{v:03d}.png").convert("L")) > 127
        if m.sum() > 200: pts.append(interior(m))
    cases.append((f"demo{v}", p, pts))
for r in [0, 10, 50]:
    p = f"/work/shared/data/lego/train/r_{r}.png"
    m = np.asarray(Image.open(p))[:,:,3] > 127; cases.append((f"lego{r}", p, [interior(m)]))
fx = sorted(os.listdir("/work/shared/data/fox/images"))
for f in [fx[0], fx[20], fx[40]]:
    p = f"/work/shared/data/fox/images/{f}"; w, h = Image.open(p).size; cases.append((f"fox{f}", p, [(w/2, h/2)]))
def masks(emb, path, pts):
    w, h = Image.open(path).size; s = 1024/max(w,h); out = []
    for (x, y) in pts:
        c = np.array([[[x*s, y*s], [0, 0]]], np.float32); l = np.array([[1, -1]], np.float32)
        r = dec.run(None, {"image_embeddings": emb, "point_coords": c, "point_labels": l,
            "mask_input": np.zeros((1,1,256,256), np.float32), "has_mask_input": np.zeros(1, np.float32),
            "orig_im_size": np.array([h, w], np.float32)})
        out.append(r[0][0,0] > 0)
    return out
os.makedirs("/tmp/sam58/py/fp32emb", exist_ok=True)
enc_ref = None
for cand in sys.argv[1:]:
    if cand.endswith("dec.onnx"): continue
    enc = ort.InferenceSession(cand, opts()); ious = []
    for name, path, pts in cases:
        cf = f"/tmp/sam58/py/fp32emb/{name}.npy"
        if not os.path.exists(cf):
            enc_ref = enc_ref or ort.InferenceSession(FP32, opts()); np.save(cf, enc_ref.run(None, {"image": prep(path)})[0])
        ref = np.load(cf); e = enc.run(None, {"image": prep(path)})[0]
        for a, b in zip(masks(ref, path, pts), masks(e, path, pts)):
            ious.append((name, float((a & b).sum() / max(1, (a | b).sum())), int(a.sum())))
    v = np.array([i for _, i, _ in ious]); worst = min(ious, key=lambda t: t[1])
    print(f"{os.path.basename(cand)}: n={len(v)} mean IoU {v.mean():.4f} worst {worst}", flush=True)
