#!/usr/bin/env python3
"""Write the hand-made part of tests/data/corrupt/ from the fuzzers' good seeds (fuzz/seeds/):
truncations, huge counts, NaN, bad UTF-8, wrong magic, broken cross-references. Each folder is a
reader (a fuzz target); tests/corrupt_inputs.rs (corrupt_corpus) runs every file through the
command that reads it. Files named crash-* are the fuzzers' finds and are not written here.
Run from the repository root: python3 fuzz/make_corrupt_corpus.py"""
import json, os, struct, zlib

SEEDS = "fuzz/seeds"
OUT = "tests/data/corrupt"


def seed(target, name):
    with open(os.path.join(SEEDS, target, name), "rb") as f:
        return f.read()


def put(reader, name, data):
    d = os.path.join(OUT, reader)
    os.makedirs(d, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def at(b, off, data):
    b = bytearray(b)
    b[off:off + len(data)] = data
    return bytes(b)


u64 = lambda v: struct.pack("<Q", v)
i32 = lambda v: struct.pack("<i", v)
f64 = lambda v: struct.pack("<d", v)
NAN = f64(float("nan"))

# --- COLMAP binary -------------------------------------------------------------------------
# cameras.bin: u64 n, then i32 id, i32 model, u64 w, u64 h, f64 params[]
cam = seed("colmap_cameras_bin", "cameras.bin")
r = "colmap_cameras_bin"
put(r, "truncated", cam[:-5])
put(r, "empty", b"")
put(r, "huge_count", at(cam, 0, u64(2**64 - 1)))
put(r, "count_times_record_overflows", at(cam, 0, u64(2**61)))
put(r, "unknown_model_id", at(cam, 12, i32(99)))
put(r, "negative_camera_id", at(cam, 8, i32(-4)))
put(r, "nan_focal_length", at(cam, 32, NAN))
put(r, "zero_width", at(cam, 16, u64(0)))
put(r, "width_beyond_u32", at(cam, 16, u64(2**40)))
put(r, "trailing_bytes", cam + b"\x00\x01\x02")

# images.bin: u64 n, i32 id, f64 q[4], f64 t[3], i32 camera, name\0, u64 n2d, (f64 x, f64 y, i64 id)*
img = seed("colmap_images_bin", "images.bin")
r = "colmap_images_bin"
name_at = 8 + 4 + 56 + 4
nul = img.index(b"\x00", name_at)
put(r, "truncated", img[:-30])
put(r, "huge_count", at(img, 0, u64(2**63)))
put(r, "huge_2d_point_count", at(img, nul + 1, u64(2**60)))
put(r, "name_without_nul", img[:name_at] + b"x" * 40)
put(r, "name_not_utf8", at(img, name_at, b"\xff\xfe"))
put(r, "quaternion_not_unit", at(img, 12, f64(3.0)))
put(r, "nan_translation", at(img, 12 + 32, NAN))
put(r, "missing_camera", at(img, 8 + 4 + 56, i32(4242)))
put(r, "nan_2d_point", at(img, nul + 1 + 8, NAN))
put(r, "unknown_point3d", at(img, nul + 1 + 8 + 16, struct.pack("<q", 777)))

# points3D.bin: u64 n, u64 id, f64 xyz, u8 rgb, f64 error, u64 len, (i32 image, i32 idx)*
pts = seed("colmap_points3d_bin", "points3D.bin")
r = "colmap_points3d_bin"
track_at = 8 + 8 + 24 + 3 + 8
put(r, "truncated", pts[:-3])
put(r, "huge_count", at(pts, 0, u64(2**64 - 2)))
put(r, "huge_track_length", at(pts, track_at, u64(2**62)))
put(r, "nan_position", at(pts, 16, NAN))
put(r, "track_unknown_image", at(pts, track_at + 8, i32(999)))
put(r, "track_index_out_of_range", at(pts, track_at + 12, i32(5000)))
put(r, "negative_track_index", at(pts, track_at + 12, i32(-1)))

# --- COLMAP text -----------------------------------------------------------------------------
ct = seed("colmap_cameras_txt", "cameras.txt").decode()
r = "colmap_cameras_txt"
lines = ct.splitlines()
data = [i for i, l in enumerate(lines) if l and not l.startswith("#")]
put(r, "bad_number", ct.replace(" 9.5 ", " 9.x5 "))
put(r, "unknown_model", ct.replace("PINHOLE", "PINHOLEZ", 1))
put(r, "not_utf8", ct.encode().replace(b"PINHOLE", b"PIN\xffHOLE", 1))
put(r, "missing_params", "\n".join(lines[:data[0]] + [" ".join(lines[data[0]].split()[:5])] + lines[data[0] + 1:]) + "\n")
put(r, "nan_param", ct.replace(" 9.5 ", " nan ", 1))
put(r, "negative_size", ct.replace(" 8 8 ", " -8 8 ", 1))

it = seed("colmap_images_txt", "images.txt").decode()
r = "colmap_images_txt"
lines = it.splitlines()
data = [i for i, l in enumerate(lines) if not l.startswith("#")]
put(r, "no_points_line", "\n".join(lines[:data[-1]]) + "\n")
put(r, "points_not_triples", "\n".join(lines[:data[1]] + [lines[data[1]] + " 1.5"] + lines[data[1] + 1:]) + "\n")
put(r, "not_utf8", it.encode().replace(b"a.png", b"a\xc3.png", 1))
first = lines[data[0]].split()
first[1] = "NaN"
put(r, "nan_quaternion", "\n".join(lines[:data[0]] + [" ".join(first)] + lines[data[0] + 1:]) + "\n")
put(r, "short_image_line", "\n".join(lines[:data[0]] + [" ".join(lines[data[0]].split()[:6])] + lines[data[0] + 1:]) + "\n")

pt = seed("colmap_points3d_txt", "points3D.txt").decode()
r = "colmap_points3d_txt"
lines = pt.splitlines()
data = [i for i, l in enumerate(lines) if not l.startswith("#")]
put(r, "odd_track", "\n".join(lines[:data[0]] + [lines[data[0]] + " 3"] + lines[data[0] + 1:]) + "\n")
put(r, "bad_number", pt.replace(lines[data[0]].split()[1], "0.1.2", 1))
f = lines[data[0]].split()
f[8] = "4242"
put(r, "track_unknown_image", "\n".join(lines[:data[0]] + [" ".join(f)] + lines[data[0] + 1:]) + "\n")
f = lines[data[0]].split()
f[1] = "inf"
put(r, "infinite_position", "\n".join(lines[:data[0]] + [" ".join(f)] + lines[data[0] + 1:]) + "\n")

# --- transforms.json -------------------------------------------------------------------------
tj = seed("transforms_json", "transforms.json").decode()
v = json.loads(tj)
r = "transforms_json"
put(r, "truncated", tj[: len(tj) // 2])
put(r, "not_utf8", tj.encode().replace(b"images/a.png", b"images/\xff.png"))
put(r, "nan_matrix", tj.replace(json.dumps(v["frames"][1]["transform_matrix"][0][0]), "NaN", 1))
put(r, "no_frames", json.dumps({**v, "frames": []}))
put(r, "frames_not_a_list", json.dumps({**v, "frames": {"a": 1}}))
put(r, "matrix_2x2", json.dumps({**v, "frames": [{**v["frames"][0], "transform_matrix": [[1, 0], [0, 1]]}]}))
put(r, "negative_width", json.dumps({**v, "w": -8}))
put(r, "huge_number", tj.replace('"fl_x": ', '"fl_x": 1e999999', 1) if '"fl_x": ' in tj else tj + "x")
put(r, "deep_nesting", '{"frames": ' + "[" * 100000 + "]" * 100000 + "}")
put(r, "zero_focal", json.dumps({**v, "fl_x": 0.0}))

# --- edit.json (through objnerf render-edit) ------------------------------------------------
ej = seed("edit_json", "edit.json").decode()
e = json.loads(ej)
o0 = e["objects"][0]
def edit_with(**top):
    return json.dumps({**e, **top})
def obj_with(**kv):
    return edit_with(objects=[{**o0, **kv}] + e["objects"][1:])
r = "edit_json"
put(r, "truncated", ej[: len(ej) // 2])
put(r, "not_utf8", ej.encode().replace(b'"mug"', b'"m\xffg"', 1))
put(r, "nan_translation", ej.replace(json.dumps(o0["translation"][0]), "NaN", 1))
put(r, "huge_number", obj_with(scale="SCALE").replace('"SCALE"', "1e999999"))
put(r, "deep_nesting", '{"objects": ' + "[" * 100000 + "]" * 100000 + "}")
put(r, "zero_scale", obj_with(scale=0))
put(r, "negative_scale", obj_with(scale=-2))
put(r, "zero_quaternion", obj_with(rotation={"w": 0, "x": 0, "y": 0, "z": 0}))
put(r, "quaternion_missing_w", obj_with(rotation={"x": 0, "y": 0, "z": 1}))
put(r, "pivot_two_numbers", obj_with(pivot=[1, 2]))
put(r, "unknown_key", obj_with(colour="red"))
put(r, "unknown_top_key", edit_with(camera={"fov": 30}))
put(r, "version_2", edit_with(version=2))
put(r, "no_version", json.dumps({k: v for k, v in e.items() if k != "version"}))
put(r, "objects_not_a_list", edit_with(objects={"mug": o0}))
put(r, "duplicate_names", edit_with(objects=[o0, o0]))
put(r, "bad_colour", obj_with(recolour={"target": "#12345g"}))
put(r, "strength_above_one", obj_with(recolour={"hue_degrees": 30, "strength": 1.5}))
put(r, "both_recolours", obj_with(recolour={"hue_degrees": 30, "target": "#2050ff"}))
put(r, "missing_model", obj_with(model="no_such_model.objf"))
put(r, "model_not_a_model", obj_with(model="edit.json"))
put(r, "background_model_and_colour", edit_with(background={"color": "#ffffff", "model": "m.objf"}))
put(r, "visible_not_bool", obj_with(visible="yes"))
put(r, "zero_metres_per_unit", edit_with(metres_per_unit=0))

# --- camera_path.json (through objnerf render-edit --path) -----------------------------------
cj = seed("camera_path_json", "camera_path.json").decode()
c = json.loads(cj)
e0 = c["camera_path"][0]
def path_with(**top):
    return json.dumps({**c, **top})
def cam_with(**kv):
    return path_with(camera_path=[{**e0, **kv}] + c["camera_path"][1:])
r = "camera_path_json"
put(r, "truncated", cj[: len(cj) // 3])
put(r, "not_utf8", cj.encode().replace(b"perspective", b"persp\xffective", 1))
put(r, "nan_matrix", cj.replace(json.dumps(e0["camera_to_world"][3]) + ",", "NaN,", 1))
put(r, "deep_nesting", '{"camera_path": ' + "[" * 100000 + "]" * 100000 + "}")
put(r, "fov_zero", cam_with(fov=0))
put(r, "fov_negative", cam_with(fov=-40))
put(r, "fov_180", cam_with(fov=180))
put(r, "unknown_camera_type", path_with(camera_type="orthographic"))
put(r, "equirectangular", path_with(camera_type="equirectangular"))
put(r, "matrix_15_numbers", cam_with(camera_to_world=e0["camera_to_world"][:15]))
put(r, "last_row_not_affine", cam_with(camera_to_world=e0["camera_to_world"][:12] + [0, 0, 1, 1]))
put(r, "not_rigid", cam_with(camera_to_world=[2 * v for v in e0["camera_to_world"][:12]] + [0, 0, 0, 1]))
put(r, "zero_width", path_with(render_width=0))
put(r, "fractional_height", path_with(render_height=12.5))
put(r, "empty_path", path_with(camera_path=[]))
put(r, "no_seconds", json.dumps({k: v for k, v in c.items() if k != "seconds"}))
put(r, "negative_fps", path_with(fps=-24))
put(r, "missing_fov", path_with(camera_path=[{k: v for k, v in e0.items() if k != "fov"}]))

# --- LLFF poses_bounds.npy -------------------------------------------------------------------
npy = seed("llff_npy", "poses_bounds.npy")
r = "llff_npy"
hlen = struct.unpack("<H", npy[8:10])[0]
body = 10 + hlen
head = npy[10:body].decode()
def npy_with(h):
    h = h.ljust(hlen - 1) + "\n"
    return npy[:8] + struct.pack("<H", len(h)) + h.encode() + npy[body:]
put(r, "wrong_magic", b"\x93NUMPZ" + npy[6:])
put(r, "truncated_body", npy[:-7])
put(r, "header_longer_than_file", at(npy, 8, struct.pack("<H", 65535))[: body + 10])
put(r, "huge_shape", npy_with(head.replace("(3, 17)", "(99999999999999999, 17)")))
put(r, "shape_overflows", npy_with(head.replace("(3, 17)", "(4611686018427387904, 4611686018427387904)")))
put(r, "fortran_order", npy_with(head.replace("False", "True")))
put(r, "big_endian", npy_with(head.replace("<f8", ">f8")))
put(r, "version_9", at(npy, 6, b"\x09"))
put(r, "nan_pose", at(npy, body, NAN))
put(r, "negative_focal", at(npy, body + 14 * 8, f64(-10.0)))

# --- Redwood trajectory.log ------------------------------------------------------------------
log = seed("redwood_trajectory", "trajectory.log").decode()
r = "redwood_trajectory"
ll = log.splitlines()
put(r, "four_lines", "\n".join(ll[:4]) + "\n")
put(r, "not_a_number", log.replace("0.5", "0.5x", 1))
put(r, "last_row_not_0001", log.replace("0 0 0 1", "0 0 1 1", 1))
put(r, "nan_entry", log.replace("-2", "NaN", 1))
put(r, "not_utf8", log.encode().replace(b"0.5", b"\xff.5", 1))
put(r, "scaled_rotation", log.replace("1 0 0 0\n", "2 0 0 0\n", 1))
put(r, "three_numbers_in_a_row", log.replace("0 1 0 0.5", "0 1 0", 1))

# --- PLY ----------------------------------------------------------------------------------------
ply = seed("ply", "sparse_pc.ply")
r = "ply"
end = ply.index(b"end_header\n") + len(b"end_header\n")
hdr = ply[:end].decode()
put(r, "no_end_header", ply[: end - 4])
put(r, "truncated_body", ply[:-2])
put(r, "huge_vertex_count", hdr.replace("element vertex 4", "element vertex 18446744073709551615").encode() + ply[end:])
put(r, "big_endian", hdr.replace("binary_little_endian", "binary_big_endian").encode() + ply[end:])
put(r, "nan_vertex", ply[:end] + struct.pack("<f", float("nan")) + ply[end + 4:])
put(r, "header_not_utf8", ply.replace(b"element vertex", b"element \xffvertex", 1))
put(r, "no_xyz", hdr.replace("property float x\n", "property float q\n").encode() + ply[end:])
put(r, "unknown_type", hdr.replace("property float y", "property half y").encode() + ply[end:])
# An element without properties and a huge count before the vertices: nothing to read, so the
# reader must not spin over 2^64 empty records (found by reading the code before fuzzing).
put(r, "empty_element_huge_count", hdr.replace("element vertex", "element junk 18446744073709551615\nelement vertex").encode() + ply[end:])
put(r, "ascii_list_length_huge", b"ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n4000000 1 2 3\n0 0 0\n")

# --- .objf ----------------------------------------------------------------------------------------
objf = seed("objf", "model.objf")
r = "objf"
hl = struct.unpack("<Q", objf[8:16])[0]
header = json.loads(objf[16:16 + hl])
arrays = objf[16 + hl:]
def objf_with(h, arrays=arrays):
    j = json.dumps(h).encode()
    return objf[:8] + u64(len(j)) + j + arrays
put(r, "wrong_magic", b"OBJNFLE\n" + objf[8:])
put(r, "truncated", objf[:-9])
put(r, "huge_header_length", at(objf, 8, u64(2**63)))
put(r, "header_not_json", objf[:16] + b"{" * hl + arrays)
put(r, "dims_overflow", objf_with({**header, "dims": [2**40, 2**40, 2**40]}))
a0 = header["arrays"][0]
put(r, "array_length_wraps", objf_with({**header, "arrays": [{**a0, "len": 2**62 - 1, "dtype": "f32"}] + header["arrays"][1:]}))
put(r, "array_end_wraps", objf_with({**header, "arrays": [{**a0, "len": (2**64 - 8) // 8, "dtype": "u64"}] + header["arrays"][1:]}))
put(r, "grid_byte_flipped", objf[:16 + hl + 5] + bytes([objf[16 + hl + 5] ^ 0x40]) + objf[16 + hl + 6:])
put(r, "nan_voxel", objf_with(header).replace(b'"voxel": ' + json.dumps(header["voxel"]).encode(), b'"voxel": NaN'))
put(r, "inverted_box", objf_with({**header, "box_min": [1.0, 1.0, 1.0], "box_max": [-1.0, -1.0, -1.0]}))
put(r, "trailing_bytes", objf + b"\x00" * 4)
put(r, "wrong_channels", objf_with({**header, "channels": 7}))

# --- PNG masks and depth ----------------------------------------------------------------------------
def chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

def png(w, h, depth, colour, raw):
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, colour, 0, 0, 0)) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")

mask = seed("mask_png", "mask.png")
r = "mask_png"
put(r, "truncated", mask[:60])
put(r, "empty", b"")
put(r, "wrong_magic", b"\x89PNX" + mask[4:])
put(r, "huge_size_no_data", png(2**31 - 1, 2**31 - 1, 8, 0, b"\x00" * 16))
put(r, "idat_short", png(64, 64, 8, 0, b"\x00" * 100))
put(r, "bad_crc", mask[:29] + b"\x00\x00\x00\x00" + mask[33:])

depth = seed("depth_png", "depth.png")
r = "depth_png"
put(r, "eight_bit", png(8, 8, 8, 0, b"".join(b"\x00" + bytes(8) for _ in range(8))))
put(r, "rgb16", png(8, 8, 16, 2, b"".join(b"\x00" + bytes(48) for _ in range(8))))
put(r, "truncated", depth[: len(depth) // 2])
put(r, "wrong_aspect", png(8, 4, 16, 0, b"".join(b"\x00" + bytes(16) for _ in range(4))))
put(r, "huge_size_no_data", png(100000, 100000, 16, 0, b"\x00" * 64))

exr = seed("depth_exr", "depth.exr")
r = "depth_exr"
put(r, "truncated", exr[: len(exr) // 2])
put(r, "wrong_magic", b"\x76\x2f\x31\x02" + exr[4:])
put(r, "header_only", exr[:120])
put(r, "empty", b"")

jpg = seed("photo_jpeg", "photo.jpg")
r = "photo_jpeg"
put(r, "empty", b"")
put(r, "png_bytes_named_jpg", mask)
put(r, "header_only", jpg[:20])
put(r, "garbage", bytes((i * 151 + 17) & 255 for i in range(700)))

# --- MobileSAM checkpoint (zip + pickle) -------------------------------------------------------------
import sys
sys.path.insert(0, "fuzz")
import make_checkpoint_seed as ck

r = "sam_checkpoint"
good = seed("sam_checkpoint", "tiny_state_dict.pt")
put(r, "truncated", good[: len(good) - 40])
put(r, "not_a_zip", b"PK\x03\x04" + bytes(60))
put(r, "no_data_pkl", ck.checkpoint(b"", []).replace(b"archive/data.pkl", b"archive/data.pkx"))
put(r, "pickle_not_a_dict", ck.checkpoint(ck.pickle_of([1, 2, 3]), []))
# Each round copies the last memo entry twice into a tuple: 2^60 values from 300 bytes.
bomb = b"\x80\x02]q\x00" + b"h\x00h\x00\x86q\x00" * 60 + b"."
put(r, "memo_doubling", ck.checkpoint(bomb, []))
def one(t, storages):
    sd = ck.collections.OrderedDict()
    sd["w"] = t
    return ck.checkpoint(ck.pickle_of(sd), storages)
big = ck.Storage("0", [1.0, 2.0])
put(r, "storage_shorter_than_pickle_says", one(ck.Tensor(ck.Storage("0", [0.0] * 50), 0, (5, 10), (10, 1)), [big]))
put(r, "view_past_storage", one(ck.Tensor(big, 1, (2,), (1,)), [big]))
put(r, "shape_overflows", one(ck.Tensor(big, 0, (2**40, 2**40), (0, 0)), [big]))
put(r, "stride_overflows", one(ck.Tensor(big, 0, (2, 2), (2**63, 1)), [big]))
put(r, "zero_stride_expands", one(ck.Tensor(big, 0, (100000, 100000), (0, 0)), [big]))
put(r, "missing_storage_record", one(ck.Tensor(ck.Storage("7", [1.0]), 0, (1,), (1,)), [big]))
