# The Python side of `objnerf bench sam` (embedded in the binary and written to a temp folder).
# Loads the same ONNX files with the same thread count, then times one session.run per command
# read from stdin ("enc I [save_path]", "dec I", "quit"), replying one JSON line each.
import json, sys, time

import numpy as np
import onnxruntime as ort

enc_path, dec_path, threads, work = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]


def options():
    o = ort.SessionOptions()
    o.intra_op_num_threads = threads
    o.inter_op_num_threads = 1
    o.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    o.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    return o


t0 = time.perf_counter()
enc = ort.InferenceSession(enc_path, options(), providers=["CPUExecutionProvider"])
dec = ort.InferenceSession(dec_path, options(), providers=["CPUExecutionProvider"])
load = time.perf_counter() - t0

spec = json.load(open(f"{work}/spec.json"))
imgs, dec_inputs = [], []
for i, s in enumerate(spec):
    imgs.append(np.fromfile(f"{work}/img{i}.f32", dtype="<f4").reshape(1, 3, 1024, 1024))
    emb = np.fromfile(f"{work}/emb{i}.f32", dtype="<f4").reshape(1, 256, 64, 64)
    dec_inputs.append({
        "image_embeddings": emb,
        "point_coords": np.array(s["coords"], dtype=np.float32).reshape(1, -1, 2),
        "point_labels": np.array(s["labels"], dtype=np.float32).reshape(1, -1),
        "mask_input": np.zeros((1, 1, 256, 256), dtype=np.float32),
        "has_mask_input": np.zeros(1, dtype=np.float32),
        "orig_im_size": np.array([s["h"], s["w"]], dtype=np.float32),
    })

print(json.dumps({"ready": True, "load_seconds": load, "version": ort.__version__}), flush=True)
for line in sys.stdin:
    parts = line.split()
    if not parts or parts[0] == "quit":
        break
    i = int(parts[1])
    if parts[0] == "enc":
        t = time.perf_counter()
        out = enc.run(None, {"image": imgs[i]})[0]
        dt = time.perf_counter() - t
        if len(parts) > 2:
            out.astype("<f4").tofile(parts[2])
    else:
        t = time.perf_counter()
        dec.run(None, dec_inputs[i])
        dt = time.perf_counter() - t
    print(json.dumps({"seconds": dt}), flush=True)
