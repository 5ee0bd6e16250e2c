"""The fully convolutional grasp-quality network and the input conditioning it expects.

After FC-GQ-CNN (Satish et al., RA-L 2019): one pass over a depth image gives a quality for
every pixel and each of ``k`` jaw angles, instead of scoring sampled grasps one crop at a
time. Ours is a small encoder with dilated convolutions (receptive field about 60 px, over
twice the open gripper plus its fingers at the canonical 4 mm per pixel), batch norm after
every convolution, and one skip connection so that quality edges stay sharp. It also
regresses the jaw width per pixel and angle.
"""

from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F

DEPTH_SCALE = 0.05  # metres of relative depth mapped to one input unit


def _block(cin: int, cout: int, size: int, *, stride: int = 1, dilation: int = 1) -> nn.Sequential:
    """Convolution, batch norm, ReLU: the normalisation is what lets it train in minutes on a CPU."""
    pad = dilation * (size - 1) // 2
    return nn.Sequential(
        nn.Conv2d(cin, cout, size, stride=stride, padding=pad, dilation=dilation, bias=False),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
    )


class GraspNet(nn.Module):
    """Depth (N, 1, H, W) in; quality logits and width fractions (N, k, H, W) each out."""

    def __init__(self, *, k: int = 8, channels: int = 48) -> None:
        super().__init__()
        self.k = k
        c = channels
        self.stem = _block(1, 16, 5)
        self.down1 = _block(16, 32, 3, stride=2)
        self.down2 = nn.Sequential(_block(32, c, 3, stride=2), _block(c, c, 3, dilation=2), _block(c, c, 3, dilation=4))
        self.up = _block(c + 32, 32, 3)
        self.head = nn.Conv2d(32, 2 * k, 1)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        h, w = x.shape[-2:]
        s1 = self.down1(self.stem(x))
        s2 = self.down2(s1)
        u = F.interpolate(s2, size=s1.shape[-2:], mode="bilinear", align_corners=False)
        out = self.head(self.up(torch.cat([u, s1], dim=1)))
        out = F.interpolate(out, size=(h, w), mode="bilinear", align_corners=False)
        return out[:, : self.k], out[:, self.k :]


def fill_holes(depth: torch.Tensor, *, rounds: int = 8) -> torch.Tensor:
    """Replace zeros (no return) by the farthest valid neighbour, repeatedly; the rest by the median.

    The farthest neighbour, because sensors lose pixels mostly at occluding edges, where the
    hidden side is the background.
    """
    d = depth
    for _ in range(rounds):
        if bool((d > 0).all()):
            break
        d = torch.where(d > 0, d, F.max_pool2d(d, 3, stride=1, padding=1))
    valid = d[d > 0]
    fallback = valid.median() if valid.numel() else torch.tensor(1.0, device=d.device)
    return torch.where(d > 0, d, fallback)


def normalise(depth: torch.Tensor) -> torch.Tensor:
    """Depth relative to the image's median (the bin floor, usually), in units of DEPTH_SCALE."""
    med = depth.flatten(-2).median(dim=-1).values[..., None, None]
    return ((depth - med) / DEPTH_SCALE).clamp(-4.0, 4.0)


def prepare(depth: torch.Tensor) -> torch.Tensor:
    """(N, 1, H, W) raw metres with zero holes -> network input."""
    return normalise(fill_holes(depth))
