import sys, numpy as np, onnxruntime as ort
from PIL import Image
sys.path.insert(0, "/tmp/sam58/py"); from common import prep
o = ort.SessionOptions(); o.intra_op_num_threads = 2
e32 = ort.InferenceSession("/root/.cache/objnerf/models/mobile_sam/encoder.onnx", o)
e8 = ort.InferenceSession("/tmp/sam58/py/v_int8_mha.onnx", o)
dec = ort.InferenceSession("/root/.cache/objnerf/models/mobile_sam/decoder.onnx", o)
def mask(enc, path, x, y):
    im = Image.open(path); w, h = im.size; s = 1024/max(w,h)
    emb = enc.run(None, {"image": prep(path)})[0]
    r = dec.run(None, {"image_embeddings": emb, "point_coords": np.array([[[x*s,y*s],[0,0]]], np.float32), "point_labels": np.array([[1,-1]], np.float32),
        "mask_input": np.zeros((1,1,256,256), np.float32), "has_mask_input": np.zeros(1, np.float32), "orig_im_size": np.array([h,w], np.float32)})
    return r[0][0,0] > 0
rows = []
for path, x, y in [("/tmp/sam58/demo/images/view_000.png", 101.5, 99.5), ("/work/shared/data/lego/train/r_0.png", 400, 400)]:
    img = np.asarray(Image.open(path).convert("RGB")).astype(np.float32)
    a, b = mask(e32, path, x, y), mask(e8, path, x, y)
    print(path, "IoU", (a&b).sum()/(a|b).sum(), "fp32 px", a.sum(), "int8 px", b.sum(), "differing px", (a^b).sum())
    def ov(m, col):
        o = img.copy(); o[m] = 0.5*o[m] + 0.5*np.array(col); return o
    d = img.copy()*0.4; d[a & b] = [255,255,255]; d[a & ~b] = [255,0,0]; d[~a & b] = [0,128,255]
    row = np.concatenate([ov(a, [0,200,0]), ov(b, [200,0,200]), d], 1)
    rows.append(Image.fromarray(row.astype(np.uint8)).resize((900, int(900*row.shape[0]/row.shape[1]))))
H = sum(r.size[1] for r in rows); out = Image.new("RGB", (900, H)); y0 = 0
for r in rows: out.paste(r, (0, y0)); y0 += r.size[1]
out.save("/tmp/sam58/overlay_fp32_int8.png")
