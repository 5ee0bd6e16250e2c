"""Training: generate labelled crops, fit the network densely, report held-out figures, save.

Dense supervision (every pixel, every angle) from the analytic labels, with the eight
symmetries of the square as augmentation: a flip or transpose of the image permutes the
angle channels, so each crop is eight consistent examples.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.nn import functional as F

from workloads.grasp_planning.data import PIXEL_SIZE, TRAIN_SEED, VAL_SEED, build
from workloads.grasp_planning.decode import decode_best
from workloads.grasp_planning.network import GraspNet, prepare
from workloads.grasp_planning.planner import save_model
from workloads.grasp_planning.quality import Gripper

SUCCESS = 0.5  # robust analytic quality at or above which a grasp counts as a success


@dataclass(frozen=True)
class TrainConfig:
    examples: int = 2400
    val: int = 200
    epochs: int = 6
    batch: int = 16
    lr: float = 3e-3
    k: int = 8
    channels: int = 32
    size: int = 80
    seed: int = 0
    workers: int = 2


def symmetry(x: torch.Tensor, q: torch.Tensor, w: torch.Tensor, *, code: int, k: int) -> tuple[torch.Tensor, ...]:
    """Apply one of the 8 square symmetries to depth (N,1,H,W) and label maps (N,k,H,W)."""
    idx = torch.arange(k)
    if code & 1:  # mirror u: angle t -> pi - t
        x, q, w = (t.flip(-1) for t in (x, q, w))
        idx = (k - idx) % k
    if code & 2:  # mirror v: angle t -> -t
        x, q, w = (t.flip(-2) for t in (x, q, w))
        idx = (k - idx) % k
    if code & 4:  # swap u and v: angle t -> pi/2 - t
        x, q, w = (t.transpose(-1, -2) for t in (x, q, w))
        idx = (k // 2 - idx) % k
    return x.contiguous(), q[:, idx].contiguous(), w[:, idx].contiguous()


def loss_fn(logits: torch.Tensor, width: torch.Tensor, q: torch.Tensor, w: torch.Tensor) -> torch.Tensor:
    """Soft binary cross-entropy on quality (positives weighted 5x), L1 on width where graspable."""
    weight = 1.0 + 4.0 * (q > 0).float()
    bce = F.binary_cross_entropy_with_logits(logits, q, weight=weight)
    mask = (q > 0.05).float()
    l1 = ((width - w).abs() * mask).sum() / mask.sum().clamp(min=1.0)
    return bce + l1


def evaluate(net: GraspNet, depth: np.ndarray, quality: np.ndarray, *, seed: int) -> dict[str, float]:
    """Top-1 success of the network against a random grasp and the label oracle, on crops."""
    rng = np.random.default_rng(seed)
    net.eval()
    model_ok, random_ok, oracle_ok = [], [], []
    with torch.inference_mode():
        for i in range(len(depth)):
            logits, _ = net(prepare(torch.from_numpy(depth[i])[None, None]))
            labels = quality[i].astype(np.float32) / 255.0
            pick = decode_best(torch.sigmoid(logits)[0].numpy(), labels, mask=depth[i] > 0)
            model_ok.append(labels[pick.angle_index, pick.v, pick.u] >= SUCCESS)
            d = depth[i]
            fg = np.argwhere((d > 0) & (d < np.median(d[d > 0]) - 0.01))
            if len(fg):
                v, u = fg[rng.integers(len(fg))]
                random_ok.append(labels[rng.integers(labels.shape[0]), v, u] >= SUCCESS)
            else:
                random_ok.append(False)
            oracle_ok.append(labels.max() >= SUCCESS)
    return {
        "model_success": float(np.mean(model_ok)),
        "random_success": float(np.mean(random_ok)),
        "oracle_success": float(np.mean(oracle_ok)),
    }


def train(cfg: TrainConfig, *, out: Path, command: str, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Build the data, train, evaluate on held-out crops, save to ``out``; return the metadata."""
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    t0 = time.monotonic()
    depth, quality, width = build(TRAIN_SEED, cfg.examples, size=cfg.size, k=cfg.k, workers=cfg.workers)
    vdepth, vquality, vwidth = build(VAL_SEED, cfg.val, size=cfg.size, k=cfg.k, workers=cfg.workers)
    log(f"data: {cfg.examples} train + {cfg.val} val crops in {time.monotonic() - t0:.0f} s")
    gripper = Gripper()
    net = GraspNet(k=cfg.k, channels=cfg.channels)
    steps = cfg.epochs * (cfg.examples // cfg.batch)
    opt = torch.optim.AdamW(net.parameters(), lr=cfg.lr, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=cfg.lr, total_steps=steps, pct_start=0.15)
    x_all = prepare(torch.from_numpy(depth)[:, None])
    step = 0
    for epoch in range(cfg.epochs):
        net.train()
        order = rng.permutation(cfg.examples)
        total = 0.0
        for b in range(cfg.examples // cfg.batch):
            idx = order[b * cfg.batch : (b + 1) * cfg.batch]
            x = x_all[idx]
            q = torch.from_numpy(quality[idx]).float() / 255.0
            w = torch.from_numpy(width[idx].astype(np.float32)) / gripper.open_width
            x, q, w = symmetry(x, q, w, code=int(rng.integers(8)), k=cfg.k)
            logits, pw = net(x)
            loss = loss_fn(logits, pw, q, w)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            step += 1
            total += float(loss.detach())
        mean_loss = total / (cfg.examples // cfg.batch)
        log(f"epoch {epoch + 1}/{cfg.epochs}: loss {mean_loss:.4f} ({time.monotonic() - t0:.0f} s)")
    figures = evaluate(net, vdepth, vquality, seed=cfg.seed)
    with torch.inference_mode():
        vx = prepare(torch.from_numpy(vdepth)[:, None])
        vq = torch.from_numpy(vquality).float() / 255.0
        vw = torch.from_numpy(vwidth.astype(np.float32)) / gripper.open_width
        logits, pw = net(vx)
        figures["val_loss"] = float(loss_fn(logits, pw, vq, vw))
        figures["val_quality_mae"] = float((torch.sigmoid(logits) - vq).abs().mean())
    figures["train_seconds"] = round(time.monotonic() - t0, 1)
    meta = {
        "k": cfg.k,
        "channels": cfg.channels,
        "pixel_size": PIXEL_SIZE,
        "gripper": asdict(gripper),
        "config": asdict(cfg),
        "command": command,
        "validation": figures,
        "torch": str(torch.__version__),
    }
    save_model(out, net, meta)
    log(f"validation on {cfg.val} held-out crops: {figures}")
    return meta
