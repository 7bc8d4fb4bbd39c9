"""Offline LPIPS: torchmetrics' LPIPS fetches AlexNet weights when it is built, which fails
without a network. It is an eval metric that a few training steps never compute, so importing
this module (before nerfstudio's models) replaces it with a stub returning 0. Only that metric."""

import torch
import torchmetrics.image.lpip as lpip


class NoLpips(torch.nn.Module):
    def __init__(self, *args, **kwargs):
        super().__init__()

    def forward(self, a, b):
        return torch.zeros(())


lpip.LearnedPerceptualImagePatchSimilarity = NoLpips
