"""Train nerfacto for a few steps on CPU on an objnerf export, masks on: nerfstudio's own data
manager, pixel sampler and model run on our dataset. Prints the loss of every step.

Usage: python ns_train_smoke.py DATA_DIR OUT_DIR STEPS

LPIPS is stubbed (lpips_stub.py): it fetches weights, which fails offline.
"""

import math
import sys
from pathlib import Path

import lpips_stub  # noqa: F401  (before nerfstudio's models import LPIPS)
import torch

from nerfstudio.configs.method_configs import method_configs  # noqa: E402  (after the stub)


def main():
    data, out, steps = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
    torch.manual_seed(0)
    cfg = method_configs["nerfacto"]
    cfg.machine.device_type = "cpu"
    cfg.vis = "tensorboard"
    cfg.output_dir = out
    cfg.max_num_iterations = steps
    cfg.pipeline.datamanager.data = data
    cfg.pipeline.datamanager.dataparser.downscale_factor = 1
    cfg.pipeline.datamanager.train_num_rays_per_batch = 1024
    cfg.pipeline.model.implementation = "torch"
    cfg.set_timestamp()
    trainer = cfg.setup(local_rank=0, world_size=1)
    trainer.setup()
    dataset = trainer.pipeline.datamanager.train_dataset
    first = dataset[0]
    kept = float(first["mask"].float().mean()) if "mask" in first else None
    print(f"nerfacto on {data}: {len(dataset)} training images, masks: {'mask' in first}"
          + (f" (first view keeps {100 * kept:.1f}% of its pixels)" if kept is not None else ""))
    losses = []
    for step in range(steps):
        loss, loss_dict, _ = trainer.train_iteration(step)
        losses.append(float(loss))
        print(f"step {step:3d}  loss {float(loss):.5f}  rgb {float(loss_dict['rgb_loss']):.5f}", flush=True)
    assert all(math.isfinite(v) for v in losses), "a loss is not finite"
    first_avg = sum(losses[:5]) / 5
    last_avg = sum(losses[-5:]) / 5
    print(f"mean loss of the first 5 steps {first_avg:.5f}, of the last 5 {last_avg:.5f}")
    assert last_avg < first_avg, "the loss did not go down"


if __name__ == "__main__":
    main()
