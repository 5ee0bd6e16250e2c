"""The grasp planner: load the weights once, then depth image + intrinsics in, best grasp out.

This is the one place that moves data between numpy and torch and picks the device, so the
CLI, the ROS node and the benchmark all plan the same way.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.nn import functional as F

from fogiac.errors import WorkloadError
from workloads.grasp_planning.camera import Intrinsics, Pose, grasp_pose, to_original_pixel
from workloads.grasp_planning.data import PIXEL_SIZE, resize_factor
from workloads.grasp_planning.decode import decode_best, tip_depth
from workloads.grasp_planning.network import GraspNet, prepare
from workloads.grasp_planning.quality import Gripper

MODEL_PATH = Path(__file__).with_name("model.pt")
FORMAT = 1


@dataclass(frozen=True)
class Grasp:
    """The planned grasp, in the input image's pixels and the camera's optical frame."""

    u: float
    v: float
    angle: float
    width: float
    quality: float
    pose: Pose

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["position"] = list(d["pose"]["position"])
        d["orientation"] = list(d["pose"]["orientation"])
        del d["pose"]
        return d


def pick_device(name: str = "auto") -> torch.device:
    """``auto`` takes CUDA when torch sees a GPU, else the CPU."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        device = torch.device(name)
    except RuntimeError:
        raise WorkloadError(f"unknown device {name!r}; use auto, cpu, cuda or cuda:N") from None
    if device.type == "cuda" and not torch.cuda.is_available():
        raise WorkloadError(f"device {name!r} asked for, but torch sees no CUDA GPU here")
    if device.type not in ("cpu", "cuda"):
        raise WorkloadError(f"unknown device {name!r}; use auto, cpu, cuda or cuda:N")
    return device


def save_model(path: Path, net: GraspNet, meta: dict[str, Any]) -> None:
    """A state dict plus plain metadata, so ``torch.load(..., weights_only=True)`` reads it."""
    state = {key: t.detach().cpu().contiguous() for key, t in net.state_dict().items()}
    torch.save({"format": FORMAT, "state_dict": state, "meta": meta}, path)


def load_model(path: Path = MODEL_PATH) -> tuple[GraspNet, dict[str, Any]]:
    path = Path(path)
    if not path.is_file():
        raise WorkloadError(f"{path}: no such model file")
    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
        if not isinstance(blob, dict) or blob.get("format") != FORMAT:
            raise ValueError(f"not format {FORMAT}")
        meta = blob["meta"]
        net = GraspNet(k=int(meta["k"]), channels=int(meta["channels"]))
        net.load_state_dict(blob["state_dict"])
    except Exception as err:  # torch raises several unrelated types for a bad file
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise WorkloadError(f"{path}: not a grasp_planning model ({first})") from None
    return net.eval(), meta


class GraspPlanner:
    """Runs the network on a depth image and decodes the best grasp into a 3-D pose."""

    def __init__(self, net: GraspNet, meta: dict[str, Any], *, device: torch.device) -> None:
        self.device = device
        self.net = net.to(device).eval()
        self.meta = meta
        self.gripper = Gripper(**meta.get("gripper", {}))

    @classmethod
    def load(cls, path: Path = MODEL_PATH, *, device: str = "auto") -> GraspPlanner:
        net, meta = load_model(path)
        return cls(net, meta, device=pick_device(device))

    @torch.inference_mode()
    def maps(self, depth: np.ndarray, intr: Intrinsics) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Quality and width maps at the canonical scale, the canonical depth, and the factor."""
        factor = resize_factor(depth, intr)
        t = torch.from_numpy(np.ascontiguousarray(depth, dtype=np.float32)).to(self.device)[None, None]
        h, w = depth.shape
        size = (max(8, round(h / factor)), max(8, round(w / factor)))
        small = F.interpolate(t, size=size, mode="nearest-exact") if size != (h, w) else t
        logits, width = self.net(prepare(small))
        quality = torch.sigmoid(logits)[0].cpu().numpy()
        width_m = (width[0].clamp(0, 1) * self.gripper.open_width).cpu().numpy()
        return quality, width_m, small[0, 0].cpu().numpy(), factor

    def plan(self, depth: np.ndarray, intr: Intrinsics) -> Grasp:
        quality, width, small, factor = self.maps(depth, intr)
        sh, sw = small.shape
        factor_u, factor_v = depth.shape[1] / sw, depth.shape[0] / sh
        valid = small > 0
        if not valid.any():
            raise WorkloadError(f"no valid depth left after resizing {depth.shape[1]}x{depth.shape[0]} to {sw}x{sh}")
        pick = decode_best(quality, width, mask=valid)
        g = self.gripper
        z = tip_depth(
            small, u=pick.u, v=pick.v, pixel_size=PIXEL_SIZE, grasp_depth=g.grasp_depth,
            open_width=g.open_width, clearance=g.table_clearance,
        )
        u, v = to_original_pixel(pick.u, pick.v, factor_u)[0], to_original_pixel(pick.u, pick.v, factor_v)[1]
        return Grasp(
            u=u, v=v, angle=pick.angle, width=pick.width, quality=pick.quality,
            pose=grasp_pose(intr, u=u, v=v, depth=z, angle=pick.angle),
        )

