#!/usr/bin/env python3
"""Write a tiny PyTorch-style checkpoint (a zip holding archive/data.pkl and archive/data/<key>)
without PyTorch, as the seed of the sam_checkpoint and sam_pickle fuzz targets: a state dict of
two float tensors, one of them a strided view. Run from the repository root."""
import collections, io, pickle, struct, sys, types, zipfile

torch = types.ModuleType("torch")
utils = types.ModuleType("torch._utils")


class FloatStorage:
    pass


FloatStorage.__module__ = "torch"
torch.FloatStorage = FloatStorage


def _rebuild_tensor_v2(*args):
    raise RuntimeError("only pickled")


_rebuild_tensor_v2.__module__ = "torch._utils"
utils._rebuild_tensor_v2 = _rebuild_tensor_v2
sys.modules["torch"] = torch
sys.modules["torch._utils"] = utils


class Storage:
    def __init__(self, key, values):
        self.key, self.values = key, values


class Tensor:
    def __init__(self, storage, offset, shape, stride):
        self.args = (storage, offset, shape, stride, False, collections.OrderedDict())

    def __reduce__(self):
        return (_rebuild_tensor_v2, self.args)


class Pickler(pickle.Pickler):
    def persistent_id(self, obj):
        if isinstance(obj, Storage):
            return ("storage", FloatStorage, obj.key, "cpu", len(obj.values))
        return None


def pickle_of(sd):
    buf = io.BytesIO()
    Pickler(buf, protocol=2).dump(sd)
    return buf.getvalue()


def checkpoint(pkl, storages):
    """A checkpoint zip: archive/data.pkl and archive/data/<key> for each Storage."""
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_STORED) as z:
        z.writestr("archive/data.pkl", pkl)
        for s in storages:
            z.writestr(f"archive/data/{s.key}", struct.pack(f"<{len(s.values)}f", *s.values))
        z.writestr("archive/version", "3\n")
    return out.getvalue()


a = Storage("0", [0.5, -1.0, 2.0, 3.25, 4.0, 5.5])
b = Storage("1", [1.0, 2.0, 3.0])
sd = collections.OrderedDict()
sd["layer.weight"] = Tensor(a, 0, (2, 3), (3, 1))
sd["layer.weight_t"] = Tensor(a, 0, (3, 2), (1, 3))
sd["layer.bias"] = Tensor(b, 1, (2,), (1,))

if __name__ == "__main__":
    pkl = pickle_of(sd)
    with open("fuzz/seeds/sam_pickle/data.pkl", "wb") as f:
        f.write(pkl)
    with open("fuzz/seeds/sam_checkpoint/tiny_state_dict.pt", "wb") as f:
        f.write(checkpoint(pkl, [a, b]))
