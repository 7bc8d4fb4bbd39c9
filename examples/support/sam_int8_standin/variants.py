# Python stand-in for the converter's variants (to measure while the Rust build crawls): int8 Linear
# layers (DynamicQuantizeMatMul, per-column int8 weights) and/or MultiHeadAttention.
import sys, numpy as np, onnx
from onnx import helper as h, numpy_helper as nh
src = "/root/.cache/objnerf/models/mobile_sam/encoder.onnx"
def build(int8, fused, out):
    m = onnx.load(src); g = m.graph
    inits = {i.name: i for i in g.initializer}
    prod = {o: n for n in g.node for o in n.output}
    cons = {}
    for n in g.node:
        for i in n.input: cons.setdefault(i, []).append(n)
    new_inits = []; extra_nodes = []
    def linear(x, name, W, b, outname):  # W: [out,in]
        if int8:
            s = np.abs(W).max(1) / 127; s[s == 0] = 1
            q = np.clip(np.round(W / s[:, None]), -127, 127).astype(np.int8).T.copy()
            new_inits.extend([nh.from_array(q, name + ".wq"), nh.from_array(s.astype(np.float32), name + ".ws"), nh.from_array(b, name + ".b")])
            extra_nodes.append(h.make_node("DynamicQuantizeMatMul", [x, name + ".wq", name + ".ws", "", name + ".b"], [outname], domain="com.microsoft", name=name + "/dqmm"))
        else:
            new_inits.extend([nh.from_array(W.T.copy(), name + ".wt"), nh.from_array(b, name + ".b")])
            extra_nodes.append(h.make_node("MatMul", [x, name + ".wt"], [outname + "_mm"], name=name + "/mm"))
            extra_nodes.append(h.make_node("Add", [name + ".b", outname + "_mm"], [outname], name=name + "/add"))
    # all linears: MatMul with a *.weight_t initializer followed by Add with *.bias
    for n in list(g.node):
        if n.op_type != "MatMul" or not n.input[1].endswith(".weight_t"): continue
        base = n.input[1][:-len(".weight_t")]
        add = cons[n.output[0]][0]; W = nh.to_array(inits[n.input[1]]).T; b = nh.to_array(inits[base + ".bias"])
        if fused and base.endswith(".qkv"):
            att = base[:-4]; nhd = W.shape[0] // 96; c = W.shape[1]
            # the proj MatMul of this attention
            proj = [p for p in g.node if p.op_type == "MatMul" and p.input[1] == att + ".proj.weight_t"][0]
            ab = nh.to_array(inits[att + ".ab"]); n_ = ab.shape[-1]
            parts = []
            for j, part in enumerate("qkv"):
                rows = [hh * 96 + j * 32 + r for hh in range(nhd) for r in range(32)]
                linear(n.input[0], f"{att}.{part}", W[rows], b[rows], f"{att}.{part}_out"); parts.append(f"{att}.{part}_out")
            new_inits.append(nh.from_array(ab.reshape(1, nhd, n_, n_), att + ".ab4"))
            extra_nodes.append(h.make_node("MultiHeadAttention", parts + ["", "", att + ".ab4"], [att + ".mha_out"], domain="com.microsoft", num_heads=nhd, name=att + "/mha"))
            proj.input[0] = att + ".mha_out"
        elif int8:
            linear(n.input[0], base, W, b, add.output[0] + "_q")
            for c2 in cons[add.output[0]]:
                for k, i in enumerate(c2.input):
                    if i == add.output[0]: c2.input[k] = add.output[0] + "_q"
    nodes = list(g.node) + extra_nodes
    # dead-code elimination from the outputs
    prod = {o: n for n in nodes for o in n.output}; live = set(); stack = [o.name for o in g.output]
    while stack:
        t = stack.pop(); n = prod.get(t)
        if n is None or id(n) in live: continue
        live.add(id(n)); stack.extend(n.input)
    keep = [n for n in nodes if id(n) in live]
    # topological order
    done = set(i.name for i in g.input) | set(i.name for i in g.initializer) | set(i.name for i in new_inits) | {""}
    order = []; pending = keep
    while pending:
        rest = []
        for n in pending:
            if all(i in done for i in n.input): order.append(n); done.update(n.output)
            else: rest.append(n)
        assert len(rest) < len(pending); pending = rest
    del g.node[:]; g.node.extend(order); g.initializer.extend(new_inits)
    used = set(i for n in order for i in n.input)
    keepi = [i for i in g.initializer if i.name in used]; del g.initializer[:]; g.initializer.extend(keepi)
    if not any(o.domain == "com.microsoft" for o in m.opset_import): m.opset_import.append(h.make_opsetid("com.microsoft", 1))
    onnx.save(m, out)
build(True, False, "/tmp/sam58/py/v_int8.onnx")
build(False, True, "/tmp/sam58/py/v_mha.onnx")
build(True, True, "/tmp/sam58/py/v_int8_mha.onnx")
print("ok")
