# python thru.py encoder.onnx [views]: # throughput over views: one 2-thread session in a loop vs two 1-thread sessions in parallel
import sys, time, threading, numpy as np, onnxruntime as ort
path = sys.argv[1]; n = int(sys.argv[2]) if len(sys.argv) > 2 else 8
x = np.random.RandomState(0).randn(1, 3, 1024, 1024).astype(np.float32)
def sess(t):
    o = ort.SessionOptions(); o.intra_op_num_threads = t; o.inter_op_num_threads = 1
    return ort.InferenceSession(path, o, providers=["CPUExecutionProvider"])
s2 = sess(2); s2.run(None, {"image": x})
a = time.perf_counter()
for _ in range(n): s2.run(None, {"image": x})
seq = (time.perf_counter() - a) / n
ss = [sess(1), sess(1)]
for s in ss: s.run(None, {"image": x})
def work(s, k):
    for _ in range(k): s.run(None, {"image": x})
a = time.perf_counter()
th = [threading.Thread(target=work, args=(s, n // 2)) for s in ss]
[t.start() for t in th]; [t.join() for t in th]
par = (time.perf_counter() - a) / n
s1 = ss[0]; a = time.perf_counter()
for _ in range(2): s1.run(None, {"image": x})
one = (time.perf_counter() - a) / 2
print(f"{path.split('/')[-1]}: 2 threads sequential {seq:.3f} s/view; two 1-thread in parallel {par:.3f} s/view ({par/seq:.3f}); 1 thread alone {one:.3f}")
