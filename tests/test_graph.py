"""fogiac graph: a pure layout of the plan, drawn to real SVG and PNG files."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.compile import compile_plan
from fogiac.graph import layout
from fogiac.manifest import load_manifest

from .conftest import EXAMPLES


def test_layout_has_sites_machines_nodes_and_topic_arrows() -> None:
    plan = compile_plan(load_manifest(EXAMPLES / "grasp-planning.yaml"))
    shape = layout(plan)
    kinds = [(b.kind, b.title) for b in shape.boxes]
    assert kinds == [("site", "edge (robot)"), ("site", "cloud: aws"), ("machine", "grasp"), ("node", "grasp")]
    machine = shape.boxes[2]
    assert machine.lines == ("g4dn.xlarge: 4 vCPU, 1 GPU, $0.53/h",)
    to_cloud, to_edge = shape.arrows
    assert to_cloud.x1 > to_cloud.x0 and to_edge.x1 < to_edge.x0
    assert to_cloud.label.splitlines() == ["/depth/camera_info", "/depth/image"]
    assert to_edge.label.splitlines() == ["/grasp", "/grasp/compute_time", "/grasp/quality"]
    assert shape.caption == "grasp-planning-dev: 1 host(s), AWS Client VPN + relay (mTLS), $0.68/h"


def test_cli_writes_svg_and_png(tmp_path: Path) -> None:
    out = tmp_path / "deploy"
    result = CliRunner().invoke(app, ["graph", str(EXAMPLES / "motion-planning.yaml"), "-o", str(out), "--target", "local"])
    assert result.exit_code == 0, result.output
    png = (tmp_path / "deploy.png").read_bytes()
    assert png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) > 5000
    svg = ET.parse(tmp_path / "deploy.svg").getroot()
    assert svg.tag.endswith("svg")
