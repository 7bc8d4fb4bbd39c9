# ONNX Runtime profile of an encoder file: kernel time by operator, then the slowest nodes.
# python prof.py encoder.onnx [runs] [nodes]  (the kernel times are the mean over runs + 1: the untimed warm-up run is profiled too)
import sys, json, time, collections, os, tempfile
import numpy as np, onnxruntime as ort
path = sys.argv[1]; runs = int(sys.argv[2]) if len(sys.argv) > 2 else 2
o = ort.SessionOptions(); o.intra_op_num_threads = 2; o.inter_op_num_threads = 1
o.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
o.enable_profiling = True; o.profile_file_prefix = tempfile.gettempdir() + "/objnerf_prof"
s = ort.InferenceSession(path, o, providers=["CPUExecutionProvider"])
x = np.random.RandomState(0).randn(1,3,1024,1024).astype(np.float32)
s.run(None, {"image": x})
for _ in range(runs):
    t = time.perf_counter(); s.run(None, {"image": x}); print("run", time.perf_counter()-t)
pf = s.end_profiling()
ev = json.load(open(pf))
by = collections.defaultdict(float); byname = collections.defaultdict(float)
for e in ev:
    if e.get("cat") == "Node" and e["name"].endswith("_kernel_time"):
        by[e["args"]["op_name"]] += e["dur"] / (runs+1)
        byname[e["name"]] += e["dur"] / (runs+1)
tot = sum(by.values())
for k, v in sorted(by.items(), key=lambda kv: -kv[1]):
    print(f"{k:30s} {v/1e3:8.1f} ms {100*v/tot:5.1f}%")
print("total", tot/1e3)
for k, v in sorted(byname.items(), key=lambda kv: -kv[1])[:int(sys.argv[3]) if len(sys.argv)>3 else 20]:
    print(f"  {k:70s} {v/1e3:8.1f}")
os.remove(pf)
