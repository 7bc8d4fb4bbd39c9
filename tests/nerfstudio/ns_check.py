"""What nerfstudio's own parsers see in objnerf's exports (for tests/nerfstudio_check.rs).

Usage: python ns_check.py JOBS.json RESULTS.json. Each job is
  {"kind": "dataset", "data": DIR, "mode": "raw" | "default", "save_transform": FILE | null}
    NerfstudioDataParserConfig on DIR: "raw" with orientation, centering and scaling off;
    "default" with nerfstudio's defaults, its poses taken back to the data frame with its own
    transform_poses_to_original_space. Masks and depth are read with nerfstudio's loaders.
  {"kind": "path", "file": FILE, "to_original": DATAPARSER_TRANSFORMS_JSON | null}
    get_path_from_json on FILE; with to_original, the poses are mapped from the viewer frame to the
    data frame with nerfstudio's transform_poses_to_original_space.
  {"kind": "dataparser", "data": DIR}
    NerfstudioDataParserConfig's defaults (what ns-train uses) on DIR: the cameras in the viewer
    frame, with the transform and scale it would save as dataparser_transforms.json.
Results are plain numbers and file names; the test compares them with objnerf's.
"""

import json
import sys
from pathlib import Path

import torch
from nerfstudio.cameras.camera_paths import get_path_from_json
from nerfstudio.cameras.cameras import CameraType
from nerfstudio.data.dataparsers.base_dataparser import transform_poses_to_original_space
from nerfstudio.data.dataparsers.nerfstudio_dataparser import NerfstudioDataParserConfig
from nerfstudio.data.datasets.base_dataset import InputDataset
from nerfstudio.data.utils.data_utils import get_depth_image_from_path, get_image_mask_tensor_from_path


def cameras_dict(cams, c2w):
    flat = lambda t: t.reshape(-1).tolist()
    return {
        "c2w": c2w.double().tolist(),
        "fx": flat(cams.fx),
        "fy": flat(cams.fy),
        "cx": flat(cams.cx),
        "cy": flat(cams.cy),
        "width": flat(cams.width),
        "height": flat(cams.height),
        "camera_type": [CameraType(int(v)).name for v in flat(cams.camera_type)],
    }


def dataset(job):
    options = dict(data=Path(job["data"]), downscale_factor=1, eval_mode="all", load_3D_points=True)
    if job["mode"] == "raw":
        options.update(orientation_method="none", center_method="none", auto_scale_poses=False)
    outputs = NerfstudioDataParserConfig(**options).setup().get_dataparser_outputs(split="train")
    cams = outputs.cameras
    c2w = cams.camera_to_worlds
    if job["mode"] == "default":
        c2w = outputs.transform_poses_to_original_space(c2w, camera_convention="opengl")
    if job.get("save_transform"):
        outputs.save_dataparser_transform(Path(job["save_transform"]))
    out = cameras_dict(cams, c2w)
    out["distortion"] = cams.distortion_params.double().tolist()
    out["image_filenames"] = [str(p) for p in outputs.image_filenames]
    masks = outputs.mask_filenames or []
    out["mask_filenames"] = [str(p) for p in masks]
    out["mask_kept"] = [int(get_image_mask_tensor_from_path(p).sum()) for p in masks]
    depths = outputs.metadata.get("depth_filenames") or []
    out["depth_filenames"] = [str(p) for p in depths]
    scale = outputs.metadata["depth_unit_scale_factor"]
    out["depth_sum_m"] = []
    for p, h, w in zip(depths, out["height"], out["width"]):
        d = get_depth_image_from_path(p, int(h), int(w), scale)
        out["depth_sum_m"].append(float(d.double().sum()))
    first = InputDataset(outputs)[0]
    out["first_image_shape"] = list(first["image"].shape)
    out["first_mask_shape"] = list(first["mask"].shape) if "mask" in first else None
    xyz = outputs.metadata.get("points3D_xyz")
    out["points"] = 0 if xyz is None else len(xyz)
    if xyz is not None:
        out["points_mean"] = xyz.double().mean(0).tolist()
        out["points_rgb_mean"] = outputs.metadata["points3D_rgb"].double().mean(0).tolist()
    out["dataparser_scale"] = float(outputs.dataparser_scale)
    return out


def camera_path(job):
    with open(job["file"]) as f:
        cams = get_path_from_json(json.load(f))
    c2w = cams.camera_to_worlds
    if job.get("to_original"):
        with open(job["to_original"]) as f:
            t = json.load(f)
        transform = torch.tensor(t["transform"], dtype=c2w.dtype)
        c2w = transform_poses_to_original_space(c2w, transform, t["scale"], camera_convention="opengl")
    return cameras_dict(cams, c2w)


def dataparser(job):
    config = NerfstudioDataParserConfig(data=Path(job["data"]), eval_mode="all")
    outputs = config.setup().get_dataparser_outputs(split="train")
    out = cameras_dict(outputs.cameras, outputs.cameras.camera_to_worlds)
    out["image_filenames"] = [str(p) for p in outputs.image_filenames]
    out["transform"] = outputs.dataparser_transform.double().tolist()
    out["scale"] = float(outputs.dataparser_scale)
    return out


def main():
    with open(sys.argv[1]) as f:
        jobs = json.load(f)["jobs"]
    run = {"dataset": dataset, "path": camera_path, "dataparser": dataparser}
    results = [run[j["kind"]](j) for j in jobs]
    with open(sys.argv[2], "w") as f:
        json.dump({"results": results}, f)


if __name__ == "__main__":
    main()
