"""Files objnerf writes and reads, parsed without Blender: PLY, nerfstudio transforms.json,
the `.objf` model header, an `extract` run's report.json, and 8-bit grey PNGs.

Nothing here touches bpy, so these readers are the same in Blender and in test scripts.
Every reader raises `ObjnerfError` naming the file and the problem.
"""

import json
import math
import os
import struct
import zlib

import numpy as np

from .errors import ObjnerfError

# ------------------------------------------------------------------------------------ PLY

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def read_ply(path):
    """Read a PLY file's vertices (x, y, z), vertex colours (0..1 floats, when present) and faces
    (lists of vertex indices, when present). Returns (xyz N x 3 float64, rgb N x 3 or None,
    faces list of index arrays). ASCII and binary (either endianness) are read."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise ObjnerfError(f"cannot read {path}: {e.strerror}") from e
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise ObjnerfError(f"{path} is not a PLY file")
    body_start = data.index(b"\n", end) + 1
    fmt, elements = None, []
    for line in data[:end].decode("ascii", "replace").splitlines()[1:]:
        tok = line.split()
        if not tok or tok[0] in ("comment", "obj_info"):
            continue
        if tok[0] == "format":
            fmt = tok[1]
        elif tok[0] == "element":
            elements.append({"name": tok[1], "count": int(tok[2]), "props": []})
        elif tok[0] == "property" and elements:
            if tok[1] == "list":
                elements[-1]["props"].append((tok[4], "list", _ply_type(path, tok[2]), _ply_type(path, tok[3])))
            else:
                elements[-1]["props"].append((tok[2], _ply_type(path, tok[1]), None, None))
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise ObjnerfError(f"{path}: unsupported PLY format '{fmt}'")
    parsed = _ply_ascii(path, data[body_start:], elements) if fmt == "ascii" else _ply_binary(
        path, data, body_start, elements, "<" if fmt == "binary_little_endian" else ">")
    vert = parsed.get("vertex")
    if vert is None or not all(k in vert for k in ("x", "y", "z")):
        raise ObjnerfError(f"{path}: no vertex element with x, y, z")
    xyz = np.stack([vert["x"], vert["y"], vert["z"]], axis=1).astype(np.float64)
    rgb = None
    if all(k in vert for k in ("red", "green", "blue")):
        rgb = np.stack([vert["red"], vert["green"], vert["blue"]], axis=1).astype(np.float64)
        if np.issubdtype(np.asarray(vert["red"]).dtype, np.integer):
            rgb /= 255.0
    faces = parsed.get("face", {}).get("vertex_indices") or parsed.get("face", {}).get("vertex_index") or []
    return xyz, rgb, faces


def _ply_type(path, name):
    if name not in _PLY_TYPES:
        raise ObjnerfError(f"{path}: unknown PLY property type '{name}'")
    return _PLY_TYPES[name]


def _ply_binary(path, data, pos, elements, endian):
    out = {}
    for el in elements:
        props, n = el["props"], el["count"]
        if not any(p[1] == "list" for p in props):
            dt = np.dtype([(p[0], endian + p[1]) for p in props])
            if pos + dt.itemsize * n > len(data):
                raise ObjnerfError(f"{path}: file ends inside element '{el['name']}'")
            arr = np.frombuffer(data, dtype=dt, count=n, offset=pos)
            pos += dt.itemsize * n
            out[el["name"]] = {p[0]: arr[p[0]] for p in props}
            continue
        if len(props) == 1 and n > 0:
            # One list per element (faces): try the fast path of equal lengths (triangles).
            _, _, ct, it = props[0]
            cnt = np.frombuffer(data, dtype=endian + ct, count=1, offset=pos)[0]
            dt = np.dtype([("n", endian + ct), ("i", endian + it, (int(cnt),))])
            if pos + dt.itemsize * n <= len(data):
                arr = np.frombuffer(data, dtype=dt, count=n, offset=pos)
                if np.all(arr["n"] == cnt):
                    out[el["name"]] = {props[0][0]: list(arr["i"].astype(np.int64))}
                    pos += dt.itemsize * n
                    continue
        cols = {p[0]: [] for p in props}
        for _ in range(n):
            for name, kind, ct, it in props:
                if kind == "list":
                    c = np.frombuffer(data, dtype=endian + ct, count=1, offset=pos)[0]
                    pos += np.dtype(ct).itemsize
                    cols[name].append(np.frombuffer(data, dtype=endian + it, count=int(c), offset=pos).astype(np.int64))
                    pos += np.dtype(it).itemsize * int(c)
                else:
                    cols[name].append(np.frombuffer(data, dtype=endian + kind, count=1, offset=pos)[0])
                    pos += np.dtype(kind).itemsize
        out[el["name"]] = {k: (v if any(p[0] == k and p[1] == "list" for p in props) else np.array(v)) for k, v in cols.items()}
    return out


def _ply_ascii(path, body, elements):
    tokens = body.split()
    pos, out = 0, {}
    try:
        for el in elements:
            cols = {p[0]: [] for p in el["props"]}
            for _ in range(el["count"]):
                for name, kind, _ct, it in el["props"]:
                    if kind == "list":
                        c = int(tokens[pos])
                        cols[name].append(np.array([int(t) for t in tokens[pos + 1:pos + 1 + c]], dtype=np.int64))
                        pos += 1 + c
                    else:
                        cols[name].append(float(tokens[pos]) if kind.startswith("f") else int(tokens[pos]))
                        pos += 1
            out[el["name"]] = {
                k: (v if any(p[0] == k and p[1] == "list" for p in el["props"]) else np.array(v, dtype=np.dtype(dict((p[0], p[1]) for p in el["props"])[k])))
                for k, v in cols.items()
            }
    except (IndexError, ValueError) as e:
        raise ObjnerfError(f"{path}: malformed ASCII PLY body ({e})") from e
    return out


# ------------------------------------------------------------------------- transforms.json


def read_json(path, what="file"):
    """Parse a JSON file; errors name the file."""
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except FileNotFoundError as e:
        raise ObjnerfError(f"{what} {path} is missing") from e
    except OSError as e:
        raise ObjnerfError(f"cannot read {what} {path}: {e.strerror}") from e
    except json.JSONDecodeError as e:
        raise ObjnerfError(f"{path} is not valid JSON: {e}") from e


_DISTORTION_KEYS = ("k1", "k2", "k3", "k4", "p1", "p2")


def read_transforms(path, undo_applied_transform=False):
    """Read a nerfstudio (or NeRF-synthetic) transforms.json into plain dicts.

    Returns {"frames": [{"name", "image", "c2w" (4x4 lists, OpenGL), "fx", "fy", "cx", "cy",
    "w", "h", "camera_model", "distortion" {k1..p2 non-zero}}], "ply": absolute path or None,
    "ply_transform": 4x4 to apply to the PLY's points, or None}.
    Intrinsics sit at the top level or per frame (a frame's values win), as objnerf reads them.

    objnerf reads `transform_matrix` as is (its capture frame is the file's frame), so by default
    so does this. A transforms.json that `objnerf export nerfstudio` wrote for another format may
    carry an `applied_transform` A (original world -> file); `undo_applied_transform` maps poses
    and points back to the original capture frame with A^-1.
    """
    tf = read_json(path, "transforms file")
    base = os.path.dirname(os.path.abspath(path))
    if not isinstance(tf, dict) or not isinstance(tf.get("frames"), list) or not tf["frames"]:
        raise ObjnerfError(f"{path}: no frames")
    undo = None
    if undo_applied_transform and tf.get("applied_transform") is not None:
        a = np.array(tf["applied_transform"], dtype=np.float64)
        if a.shape == (3, 4):
            a = np.vstack([a, [0, 0, 0, 1]])
        if a.shape != (4, 4) or not np.all(np.isfinite(a)):
            raise ObjnerfError(f"{path}: applied_transform must be a finite 3x4 or 4x4 matrix")
        undo = np.linalg.inv(a)
    frames = []
    for i, fr in enumerate(tf["frames"]):
        k = {key: fr.get(key, tf.get(key)) for key in (
            "camera_model", "fl_x", "fl_y", "cx", "cy", "w", "h", "camera_angle_x", "camera_angle_y",
            *_DISTORTION_KEYS)}
        fp = fr.get("file_path")
        m = fr.get("transform_matrix")
        if not isinstance(fp, str) or not isinstance(m, list) or len(m) not in (3, 4):
            raise ObjnerfError(f"{path}: frame {i} needs file_path and a 3x4 or 4x4 transform_matrix")
        c2w = [list(map(float, row)) for row in m[:3]] + [[0.0, 0.0, 0.0, 1.0]]
        if any(len(r) != 4 or not all(math.isfinite(v) for v in r) for r in c2w):
            raise ObjnerfError(f"{path}: frame {i} ('{fp}') has a malformed transform_matrix")
        if undo is not None:
            c2w = (undo @ np.array(c2w)).tolist()
        image = os.path.normpath(os.path.join(base, fp))
        if not os.path.splitext(image)[1] and os.path.exists(image + ".png"):
            image += ".png"  # NeRF-synthetic leaves the extension out
        w, h = k["w"], k["h"]
        if w is None or h is None:
            w, h = _image_size(image, path)
        fx = k["fl_x"]
        if fx is None:
            if k["camera_angle_x"] is None:
                raise ObjnerfError(f"{path}: frame {i} has no focal length (fl_x or camera_angle_x)")
            fx = 0.5 * w / math.tan(0.5 * k["camera_angle_x"])
        fy = k["fl_y"]
        if fy is None:
            fy = 0.5 * h / math.tan(0.5 * k["camera_angle_y"]) if k["camera_angle_y"] is not None else fx
        frames.append({
            "name": os.path.splitext(os.path.basename(fp))[0],
            "image": image,
            "c2w": c2w,
            "fx": float(fx), "fy": float(fy),
            "cx": float(k["cx"] if k["cx"] is not None else 0.5 * w),
            "cy": float(k["cy"] if k["cy"] is not None else 0.5 * h),
            "w": int(round(w)), "h": int(round(h)),
            "camera_model": k["camera_model"] or "PINHOLE",
            "distortion": {d: float(k[d]) for d in _DISTORTION_KEYS if k[d]},
        })
    ply = tf.get("ply_file_path")
    return {"frames": frames, "ply": os.path.normpath(os.path.join(base, ply)) if ply else None,
            "ply_transform": undo}


def _image_size(image, tf_path):
    """(w, h) from a PNG or JPEG header, for transforms files that leave w and h out."""
    try:
        with open(image, "rb") as f:
            head = f.read(64 * 1024)
    except OSError as e:
        raise ObjnerfError(f"{tf_path}: image {image} is missing and the file gives no w, h") from e
    if head.startswith(b"\x89PNG"):
        return struct.unpack(">II", head[16:24])
    i = 2
    while head[:2] == b"\xff\xd8" and i + 9 < len(head):
        seg_len = struct.unpack(">H", head[i + 2:i + 4])[0]
        if head[i + 1] in (0xC0, 0xC1, 0xC2):
            h, w = struct.unpack(">HH", head[i + 5:i + 9])
            return w, h
        i += 2 + seg_len
    raise ObjnerfError(f"{tf_path}: cannot tell the size of {image}; give w and h")


# ------------------------------------------------------------------------------- objf, run


OBJF_MAGIC = b"OBJNFLD\n"


def read_objf_header(path):
    """The JSON header of an objnerf model file (`.objf`): magic, u64 LE length, JSON."""
    try:
        with open(path, "rb") as f:
            magic = f.read(8)
            if magic != OBJF_MAGIC:
                raise ObjnerfError(f"{path} is not an objnerf model file (.objf)")
            (n,) = struct.unpack("<Q", f.read(8))
            if n > 64 * 1024 * 1024:
                raise ObjnerfError(f"{path}: header length {n} is implausible")
            return json.loads(f.read(n).decode("utf-8"))
    except FileNotFoundError as e:
        raise ObjnerfError(f"model file {path} is missing") from e
    except (struct.error, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ObjnerfError(f"{path}: unreadable model header ({e})") from e


def model_pivot(header):
    """The default pivot objnerf uses for a model: the centre of the field's box (`box_min`,
    `box_max` in the header), taken through the header's object-to-world `world_transform`
    (row-major 4x4; the identity for every model `objnerf train` writes)."""
    lo, hi = header["box_min"], header["box_max"]
    c = [(float(a) + float(b)) / 2.0 for a, b in zip(lo, hi)]
    m = header.get("world_transform") or [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    return [sum(m[r][j] * c[j] for j in range(3)) + m[r][3] for r in range(3)]


def read_run(run_dir):
    """An `objnerf extract` run folder: report.json and, per object, the files the add-on uses.

    Returns {"report", "scene", "objects": [{"name", "model", "mesh_ply", "points_ply"}]}.
    Missing files are an error naming each one.
    """
    if not os.path.isdir(run_dir):
        raise ObjnerfError(f"run folder {run_dir} does not exist")
    report = read_json(os.path.join(run_dir, "report.json"), "run report")
    objs = report.get("objects")
    if not isinstance(objs, list) or not objs:
        raise ObjnerfError(f"{run_dir}/report.json lists no objects")
    out, missing = [], []
    for o in objs:
        name = o.get("name")
        if not name:
            raise ObjnerfError(f"{run_dir}/report.json: an object has no name")
        entry = {
            "name": name,
            "model": os.path.join(run_dir, name, "model.objf"),
            "mesh_ply": os.path.join(run_dir, name, "mesh.ply"),
            "points_ply": os.path.join(run_dir, "segment", f"{name}_points.ply"),
        }
        missing += [p for k, p in entry.items() if k != "name" and not os.path.isfile(p)]
        out.append(entry)
    if missing:
        raise ObjnerfError(f"run folder {run_dir} is missing " + ", ".join(os.path.relpath(p, run_dir) for p in missing))
    return {"report": report, "scene": report.get("scene"), "objects": out}


# ------------------------------------------------------------------------------------- PNG


def write_png(path, pixels):
    """Write a PNG without colour management, so values land in the file exactly: grey H x W
    (uint8, or uint16 for 16-bit depth in millimetres) or RGB H x W x 3 (uint8)."""
    a = np.asarray(pixels)
    depth = 16 if a.dtype == np.uint16 else 8
    a = np.ascontiguousarray(a, dtype=">u2" if depth == 16 else np.uint8)
    if a.ndim == 2:
        colour_type, rows = 0, a
    elif a.ndim == 3 and a.shape[2] == 3 and depth == 8:
        colour_type, rows = 2, a.reshape(a.shape[0], -1)
    else:
        raise ValueError(f"write_png: need H x W or H x W x 3 (8-bit), got {a.shape} {a.dtype}")
    h, w = a.shape[:2]
    raw = b"".join(b"\x00" + rows[r].tobytes() for r in range(h))

    def chunk(tag, body):
        return struct.pack(">I", len(body)) + tag + body + struct.pack(">I", zlib.crc32(tag + body) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, colour_type, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(png)
    os.replace(tmp, path)
