# ONNX Runtime profile of an encoder file, kernel time summed per stage/block and operator (3 runs).
# python prof3.py encoder.onnx
import sys, json, collections, os, re, tempfile
import numpy as np, onnxruntime as ort
path = sys.argv[1]; runs = 3
o = ort.SessionOptions(); o.intra_op_num_threads = 2; o.inter_op_num_threads = 1
o.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
o.enable_profiling = True; o.profile_file_prefix = tempfile.gettempdir() + "/objnerf_prof"
s = ort.InferenceSession(path, o, providers=["CPUExecutionProvider"])
x = np.random.RandomState(0).randn(1,3,1024,1024).astype(np.float32)
for _ in range(runs): s.run(None, {"image": x})
ev = json.load(open(s.end_profiling()))
by = collections.defaultdict(float)
for e in ev:
    if e.get("cat") == "Node" and e["name"].endswith("_kernel_time"):
        n = e["name"]; m = re.search(r"layers\.(\d)/(blocks\.\d|downsample)(/attn|/mlp)?", n)
        key = (m.group(0) if m else ("neck" if "neck" in n else ("patch" if "patch" in n else "other"))) + " " + e["args"]["op_name"]
        by[key] += e["dur"] / runs / 1e3
for k, v in sorted(by.items()):
    if v > 3: print(f"{k:50s} {v:7.1f}")
print("total", sum(by.values()))
