"""The live progress table `up` and `down` show: one row per changing resource, with its timer."""

from __future__ import annotations

import pytest
from pulumi.automation import events
from rich.console import Console

from fogiac.cli.deploy import _Progress
from fogiac.pulumi_engine.events import translated


def _pre(op: str, urn: str, typ: str) -> events.EngineEvent:
    meta = events.StepEventMetadata(op=events.OpType(op), urn=urn, type=typ, provider="")
    return events.EngineEvent(1, 0, resource_pre_event=events.ResourcePreEvent(meta))


def _done(op: str, urn: str, typ: str) -> events.EngineEvent:
    meta = events.StepEventMetadata(op=events.OpType(op), urn=urn, type=typ, provider="")
    return events.EngineEvent(2, 0, res_outputs_event=events.ResOutputsEvent(meta))


def test_rows_and_timers(monkeypatch: pytest.MonkeyPatch) -> None:
    now = [10.0]
    progress = _Progress()
    progress.clock = progress.timers.clock = lambda: now[0]
    monkeypatch.setattr(progress.live, "start", lambda *a, **k: None)
    feed = translated(progress)  # what the aws engine hands the lifecycle: neutral progress events
    assert feed is not None
    vpc = "urn:pulumi:s::fogiac::aws:ec2/vpc:Vpc::m-dev-vpc"
    endpoint = "urn:pulumi:s::fogiac::aws:ec2clientvpn/endpoint:Endpoint::m-dev-endpoint"
    feed(_pre("create", vpc, "aws:ec2/vpc:Vpc"))
    feed(_pre("create", endpoint, "aws:ec2clientvpn/endpoint:Endpoint"))
    now[0] = 14.0
    feed(_done("create", vpc, "aws:ec2/vpc:Vpc"))
    now[0] = 610.0
    console = Console(width=120, record=True, color_system=None)
    console.print(progress._table())
    lines = [ln.strip() for ln in console.export_text().splitlines() if "m-dev" in ln]
    assert lines[0].startswith("✓") and "create m-dev-vpc" in lines[0] and lines[0].endswith("4s")
    assert lines[1].startswith("…") and "create m-dev-endpoint" in lines[1] and lines[1].endswith("600s")
