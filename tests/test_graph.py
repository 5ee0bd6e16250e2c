"""fogiac graph: a pure layout of the plan, drawn to real SVG and PNG files."""

from __future__ import annotations

import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.diagram import layout

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
    assert shape.caption == "grasp-planning-dev: 1 host(s), fogiac relay through AWS Client VPN, $0.68/h"


def test_cli_writes_svg_and_png(tmp_path: Path) -> None:
    out = tmp_path / "deploy"
    result = CliRunner().invoke(app, ["graph", str(EXAMPLES / "motion-planning.yaml"), "-o", str(out), "--target", "local"])
    assert result.exit_code == 0, result.output
    png = (tmp_path / "deploy.png").read_bytes()
    assert png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) > 5000
    svg = ET.parse(tmp_path / "deploy.svg").getroot()
    assert svg.tag.endswith("svg")


def test_cli_without_matplotlib_says_so_in_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """matplotlib is an optional extra: missing, ``fogiac graph`` names the extra, no traceback."""
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib now raises ImportError
    manifest = EXAMPLES / "motion-planning.yaml"
    result = CliRunner().invoke(app, ["graph", str(manifest), "-o", str(tmp_path / "deploy"), "--target", "local"])
    assert result.exit_code == 1
    one_line = r"error: matplotlib is not installed \([^\n]+\); install it with: pip install 'fogiac\[workloads\]'\n"
    assert re.fullmatch(one_line, result.output), result.output
    assert not list(tmp_path.iterdir())
