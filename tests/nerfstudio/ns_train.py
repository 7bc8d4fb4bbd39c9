"""nerfstudio's own `ns-train` (the entrypoint of nerfstudio.scripts.train, as the console script
runs it), offline: LPIPS is stubbed first (lpips_stub.py). Writes what ns-train writes, among it
the run's dataparser_transforms.json.

Usage: python ns_train.py ARGS...   (ns-train's arguments)
"""

import sys

import lpips_stub  # noqa: F401  (before nerfstudio's models import LPIPS)
from nerfstudio.scripts.train import entrypoint  # noqa: E402

if __name__ == "__main__":
    sys.argv = ["ns-train", *sys.argv[1:]]
    entrypoint()
