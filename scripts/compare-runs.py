"""Compare two scripts/behaviour-runs output folders: model arrays by their sha256, PNG/GLB/PLY/GIF/EXR byte for byte."""
import json, sys, os, hashlib, glob
A, B = sys.argv[1], sys.argv[2]
def arrays(p):
    b = open(p, 'rb').read(400000); i = b.index(b'{'); d = 0
    for j in range(i, len(b)):
        if b[j:j+1] == b'{': d += 1
        elif b[j:j+1] == b'}':
            d -= 1
            if d == 0: break
    return [(a['name'], a['sha256']) for a in json.loads(b[i:j+1])['arrays']]
same = diff = 0
for root, _, files in os.walk(A):
    for f in files:
        pa = os.path.join(root, f); pb = os.path.join(B, os.path.relpath(pa, A))
        if not os.path.exists(pb): print('missing', pb); diff += 1; continue
        if f.endswith('.objf'):
            ok = arrays(pa) == arrays(pb)
        elif f.endswith(('.png', '.glb', '.ply', '.gif', '.exr')):
            ok = open(pa,'rb').read() == open(pb,'rb').read()
        else:
            continue
        same += ok; diff += (not ok)
        if not ok: print('DIFF', os.path.relpath(pa, A))
print(f'{same} files identical (model arrays by sha256, images/meshes byte for byte), {diff} differ')
