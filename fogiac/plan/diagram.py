"""``fogiac graph``: the deployment drawn as SVG and PNG.

Edge and cloud sites, the machines with their hardware, the nodes on them, and the topics that
cross the relay or the VPN. The layout is a pure function of the Plan (:func:`layout`); drawing
it with matplotlib is the thin shell (:func:`draw`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from fogiac.extras import need
from fogiac.net import middleware
from fogiac.plan.model import HostSpec, Plan


@dataclass(frozen=True)
class Box:
    x: float
    y: float
    w: float
    h: float
    title: str
    lines: tuple[str, ...]
    kind: str  # site | machine | node


@dataclass(frozen=True)
class Arrow:
    x0: float
    y0: float
    x1: float
    y1: float
    label: str


@dataclass(frozen=True)
class Drawing:
    width: float
    height: float
    boxes: tuple[Box, ...]
    arrows: tuple[Arrow, ...]
    caption: str


def _hardware(host: HostSpec) -> str:
    if host.machine == "lab":
        return f"lab machine, {host.gpus} GPU" if host.gpus else "lab machine"
    gpu = f", {host.gpus} GPU" if host.gpus else ""
    price = f", ${host.usd_per_hour:.2f}/h" if host.usd_per_hour else ""
    if host.usd_per_hour is None:  # the catalogue has no price there: unknown, never free
        price = ", cost unknown"
    return f"{host.machine}: {host.vcpus} vCPU{gpu}{price}"


def layout(plan: Plan) -> Drawing:
    row_h, gap = 2.7, 0.9
    height = max(4.0, len(plan.hosts) * (row_h + gap) + 1.2)
    carrier = middleware.get(plan.middleware)
    link = carrier.label.split(":")[0] + (f" through {plan.vpn.label}" if plan.vpn is not None else "")
    boxes = [
        Box(0.3, 0.3, 3.8, height - 0.6, "edge (robot)", (f"ROS {plan.ros_distro}", carrier.edge_side[:40]), "site"),
        Box(9.6, 0.3, 8.2, height - 0.6, f"cloud: {plan.target}",
            (plan.region if plan.network is not None else "",), "site"),
    ]
    arrows: list[Arrow] = []
    for i, host in enumerate(plan.hosts):
        top = height - 1.3 - i * (row_h + gap)
        route = next((r for r in plan.routes if r.host == host.name), None)
        replica = (f"replica {route.replica.index + 1}/{route.replica.count}" + (f", {host.zone}" if host.zone else "")
                   if route is not None and route.replica is not None else "")
        boxes.append(Box(9.9, top - row_h, 7.6, row_h, host.name, (_hardware(host),) + ((replica,) if replica else ()),
                         "machine"))
        for j, name in enumerate(host.nodes):
            node = plan.node(name)
            what = node.workload or node.image or (f"{node.launch.package}/{node.launch.file}" if node.launch else "")
            lines = (what[:38], "GPU" if node.gpu else "CPU")
            boxes.append(Box(10.1 + j * 3.7, top - row_h + 0.15, 3.5, 1.25, node.name, lines, "node"))
        if route is None:
            continue
        y = top - row_h / 2
        auto = ("(auto-discovered)",) if route.auto else ()
        ins = "\n".join(route.to_cloud + route.listed + auto)
        outs = "\n".join(route.to_edge + auto)
        arrows.append(Arrow(4.1, y + 0.4, 9.9, y + 0.4, ins))
        arrows.append(Arrow(9.9, y - 0.4, 4.1, y - 0.4, outs))
    caption = f"{plan.stack}: {len(plan.hosts)} host(s), {link}"
    if plan.unknown_costs:  # a sum that leaves machines out is at least that much
        caption += f", at least ${plan.hourly_usd:.2f}/h plus {len(plan.unknown_costs)} unknown"
    elif plan.hourly_usd:
        caption += f", ${plan.hourly_usd:.2f}/h"
    return Drawing(18.0, height, tuple(boxes), tuple(arrows), caption)


_COLOURS = {"site": ("#f4f6f8", "#5b6770"), "machine": ("#e3f0fb", "#2f6ea5"), "node": ("#fff4dc", "#b07a12")}


def draw(plan: Plan, out_stem: Path) -> tuple[Path, Path]:
    """Write ``<stem>.svg`` and ``<stem>.png``; returns both paths.

    matplotlib is an optional extra, so it is imported here through :func:`need`: without it,
    ``fogiac graph`` fails in one line naming the extra, and the rest of fogiac never loads it.
    """
    need("matplotlib").use("Agg")  # before pyplot: no display needed
    plt = need("matplotlib.pyplot")
    patches = need("matplotlib.patches")

    shape = layout(plan)
    fig, ax = plt.subplots(figsize=(shape.width * 0.75, shape.height * 0.75))
    ax.set_xlim(0, shape.width)
    ax.set_ylim(0, shape.height + 0.6)
    ax.axis("off")
    for box in shape.boxes:
        face, edge = _COLOURS[box.kind]
        ax.add_patch(
            patches.FancyBboxPatch((box.x, box.y), box.w, box.h, boxstyle="round,pad=0.05", fc=face, ec=edge, lw=1.4)
        )
        ax.text(box.x + 0.15, box.y + box.h - 0.3, box.title, fontsize=10, weight="bold", va="top", color=edge)
        for k, line in enumerate(text for text in box.lines if text):
            ax.text(box.x + 0.15, box.y + box.h - 0.75 - k * 0.38, line, fontsize=8, va="top")
    for arrow in shape.arrows:
        ax.add_patch(
            patches.FancyArrowPatch(
                (arrow.x0, arrow.y0), (arrow.x1, arrow.y1), arrowstyle="-|>", mutation_scale=14, lw=1.3
            )
        )
        upward = arrow.x1 > arrow.x0
        ax.text((arrow.x0 + arrow.x1) / 2, arrow.y0 + (0.1 if upward else -0.1), arrow.label, fontsize=7,
                ha="center", va="bottom" if upward else "top", linespacing=1.3)
    ax.text(shape.width / 2, shape.height + 0.3, shape.caption, fontsize=11, ha="center", weight="bold")
    out_stem.parent.mkdir(parents=True, exist_ok=True)
    svg, png = out_stem.with_suffix(".svg"), out_stem.with_suffix(".png")
    fig.savefig(svg, bbox_inches="tight")
    fig.savefig(png, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return svg, png
