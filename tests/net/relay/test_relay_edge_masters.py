"""A fleet's ``up --start-edge-master`` starts every robot's demo master before it waits for any to answer.

Each roscore takes a second or more to answer (longer on a loaded machine), so starting them one by one and
waiting after each made a three-robot ``up`` wait three master starts in turn. Real masters, started the way
``up`` starts them (the relay deployment's ``prepare_edge`` for a three-robot plan); the test only watches the
order of the starts and of the waits, then checks every master answers and is stopped cleanly.
"""

from __future__ import annotations

import shutil
import xmlrpc.client
from pathlib import Path
from typing import Any

import pytest

from fogiac.manifest.schema import load_manifest
from fogiac.net.relay import deploy
from fogiac.plan.compile import compile_plan
from fogiac.procs import free_port
from fogiac.provision import supervise

pytestmark = [pytest.mark.ros,
              pytest.mark.skipif(shutil.which("rosmaster") is None, reason="needs Debian's ros-core (rosmaster)")]


def test_every_robots_master_is_started_before_any_is_waited_for(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    masters = {f"http://127.0.0.1:{free_port()}/": f"{deploy.EDGE_MASTER}@arm{n}" for n in (1, 2, 3)}
    robots = "".join(f'  - {{name: {name.partition("@")[2]}, ros_master: "{uri}"}}\n' for uri, name in masters.items())
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(f"""name: masters
cloud: {{provider: local}}
robots:
{robots}nodes:
  - {{name: planner, machine: t3.micro, command: [sleep, "1"], topics: {{in: [/plan/request], out: [/plan/reply]}}}}
""")
    plan = compile_plan(load_manifest(manifest))
    folder = tmp_path / "edge"
    events: list[str] = []
    real_start, real_poll = supervise.start, deploy.poll

    def start(folder: Path, name: str, argv: list[str]) -> str:
        events.append(name)
        return real_start(folder, name, argv)

    def poll(*args: Any, **kwargs: Any) -> Any:  # every wait of the deployment's for a master
        events.append("wait")
        return real_poll(*args, **kwargs)

    monkeypatch.setattr(supervise, "start", start)
    monkeypatch.setattr(deploy, "poll", poll)
    try:
        deploy.RelayDeployment().prepare_edge(plan, plan.edges[0].entry, folder=folder, start=True)
        starts = [i for i, event in enumerate(events) if event != "wait"]
        assert sorted(events[i] for i in starts) == sorted(masters.values()), events
        assert "wait" not in events[starts[0]:starts[-1]], events  # no master waited for before the last started
        for uri in masters:  # each answers, on its own port
            assert xmlrpc.client.ServerProxy(uri).getPid("/test")[0] == 1
    finally:
        supervise.stop_many(folder, list(masters.values()))
    assert not any(supervise.pid_alive(int(p.read_text().split()[0])) for p in folder.glob("*.pid"))
