# interleaved timing of several encoders on one real image, plus embedding error vs the first
import sys, time, numpy as np, onnxruntime as ort
from PIL import Image
paths = sys.argv[2:]; runs = int(sys.argv[1])
def opts():
    o = ort.SessionOptions(); o.intra_op_num_threads = 2; o.inter_op_num_threads = 1
    o.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL; return o
ss = [ort.InferenceSession(p, opts(), providers=["CPUExecutionProvider"]) for p in paths]
img = np.asarray(Image.open("/tmp/sam58/demo/images/view_000.png").convert("RGB").resize((1024,768)), dtype=np.float32)
mean = np.array([123.675,116.28,103.53]); std = np.array([58.395,57.12,57.375])
x = np.zeros((1,3,1024,1024), np.float32); x[0,:,:768,:] = ((img-mean)/std).transpose(2,0,1)
outs = [s.run(None, {"image": x})[0] for s in ss]
ref = outs[0]
for p, o in zip(paths, outs):
    print(p, "max abs", float(np.abs(o-ref).max()), "rel rms", float(np.sqrt(((o-ref)**2).mean()/ (ref**2).mean())))
ts = [[] for _ in ss]
for r in range(runs):
    order = list(range(len(ss))) if r % 2 == 0 else list(reversed(range(len(ss))))
    for i in order:
        t = time.perf_counter(); ss[i].run(None, {"image": x}); ts[i].append(time.perf_counter()-t)
for p, t in zip(paths, ts):
    print(f"{p}: median {np.median(t):.3f}  ratio {np.median(np.array(t)/np.array(ts[0])):.3f}")
