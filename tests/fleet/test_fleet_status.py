"""``fogiac status`` shows one row per robot of a fleet, and ``fogiac ls`` the robot count.

The stack record is written through :class:`fogiac.state.StackState` as ``up`` writes it (the deployment and
the edges list, :func:`fogiac.lifecycle.edge.record_edge`), and each robot's edge stats file as the relay's
edge end writes it (:func:`fogiac.net.relay.stats.write_stats`, at the path ``up`` gives that robot's edge end):
the thing under test is what status reads from them and how it shows it, not the relay.
"""

from __future__ import annotations

import json
from io import StringIO
from pathlib import Path

from rich.console import Console
from typer.testing import CliRunner

from fogiac import deployment
from fogiac.cli import app
from fogiac.lifecycle.edge import edge_dir, record_edge
from fogiac.lifecycle.robots import robot_status, robots_table
from fogiac.manifest.revision import load_revision
from fogiac.net.relay.stats import RelayStats, TopicStats, write_stats
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan
from fogiac.state import StackState
from tests.plan.test_fleet import FLEET

runner = CliRunner()
WIDE = {"COLUMNS": "300"}


def _deploy(folder: Path, text: str = FLEET) -> tuple[Path, Plan]:
    manifest = folder / "fogiac.yaml"
    manifest.write_text(text)
    plan = compile_plan(load_revision(str(manifest)).manifest)
    deployment.begin(plan, manifest)
    deployment.finish(plan, manifest, plan_digest="0" * 64)
    record_edge(plan, {"target": plan.target, "edge_master": plan.edge_master,
                       "relays": {route.host: f"127.0.0.1:{route.port}" for route in plan.routes},
                       "started_edge_master": False, "nodes": {n.name: n.host for n in plan.nodes}})
    return manifest, plan


def _topic(topic: str, direction: str, msgs: int, latency: float | None, p99: float | None = None,
           drops: int = 0) -> TopicStats:
    return TopicStats(topic=topic, direction=direction, msgs_per_s=0.0, bytes_per_s=0.0, msgs=msgs, bytes=msgs * 64,
                      drops=drops, latency_ms=latency, latency_p99_ms=p99, compression="none")


def _stats(plan: Plan, host: str, robot: str, stats: RelayStats) -> None:
    """The robot's edge end's stats file for its link to ``host``, where up has it write it."""
    folder = edge_dir(plan)
    folder.mkdir(parents=True, exist_ok=True)  # as the edge end's supervisor has it
    write_stats(folder / f"relay-edge-{host}@{robot}.stats.json", stats)


def test_status_shows_each_robot_its_link_topics_latency_and_requests_served(tmp_path: Path) -> None:
    manifest, plan = _deploy(tmp_path)
    # arm1: both links up; 5 requests out to the planner, 5 paths back, 2 grasp requests and 2 replies.
    # (the edge end's own words: "out" it sends over the link, "in" it publishes on the robot's master)
    _stats(plan, "planner", "arm1", RelayStats("edge", True, 1.5, 0.0, 0, (
        _topic("/plan/request", "out", 5, 3.0, 4.0), _topic("/plan/path", "in", 5, 5.0, 9.0))))
    _stats(plan, "grasp", "arm1", RelayStats("edge", True, 0.8, 0.0, 0, (
        _topic("/grasp/request", "out", 2, 2.0, 2.5), _topic("/grasp/reply", "in", 2, 7.0, 12.0, drops=1))))
    # arm2: its planner link up, nothing answered yet; its grasp link down, one topic refused (not its own)
    _stats(plan, "planner", "arm2", RelayStats("edge", True, 2.0, 0.0, 0, (
        _topic("/plan/request", "out", 3, 4.0, 4.0), _topic("/plan/path", "in", 0, None))))
    _stats(plan, "grasp", "arm2", RelayStats("edge", False, None, 0.0, 3, (), refused=1))
    # arm3: no stats file at all (its edge end never ran)

    rows = {r["robot"]: r for r in robot_status(plan)}
    assert list(rows) == ["arm1", "arm2", "arm3"]
    one = rows["arm1"]
    assert (one["links_up"], one["rtt_ms"], one["sent"], one["served"], one["drops"]) == (2, 0.8, 7, 7, 1)
    assert one["topics"] == ["/grasp/reply", "/grasp/request", "/plan/path", "/plan/request"]
    assert one["latency_ms"] == 4.0 and one["latency_p99_ms"] == 12.0  # median of 2, 3, 5, 7; the worst p99
    two = rows["arm2"]
    assert (two["links_up"], two["served"], two["refused"], two["topics"]) == (1, 0, 1, ["/plan/request"])
    assert rows["arm3"]["links_up"] == 0 and rows["arm3"]["edge_master"] == "http://127.0.0.1:11314"

    shown = runner.invoke(app, ["status", str(manifest)], env=WIDE)
    assert shown.exit_code == 0, shown.output
    lines = shown.output.splitlines()
    assert any(line.startswith("robots (3; served: replies the nodes sent the robot)") for line in lines)
    cells = {line.split("│")[1].strip(): [c.strip() for c in line.split("│")[2:-1]]
             for line in lines if line.startswith("│ arm")}
    assert cells["arm1"][:2] == ["http://127.0.0.1:11312", "up 2/2 (0.80 ms)"]
    assert cells["arm1"][3:] == ["4.00 / 12.00", "7", "7", "1", "0", "not running"]
    assert cells["arm2"][1] == "partly up 1/2 (2.00 ms)" and cells["arm2"][4:7] == ["3", "0", "0"]
    assert cells["arm2"][7] == "1"  # the topic its cloud end refused it
    assert cells["arm3"][1:3] == ["down 0/2", "-"] and cells["arm3"][3] == "- / -"
    assert "planner (arm2)" in shown.output  # the relayed topics say whose link each row is

    doc = json.loads(runner.invoke(app, ["status", str(manifest), "--json"]).output)
    assert [r["robot"] for r in doc["robots"]] == ["arm1", "arm2", "arm3"] and doc["robots"][0]["served"] == 7

    listed = runner.invoke(app, ["ls"], env=WIDE).output
    row = next(line for line in listed.splitlines() if line.startswith("│ lab-dev "))
    header = next(line for line in listed.splitlines() if "stack" in line and "robots" in line)
    assert [c.strip() for c in row.split("│")][header.split("┃").index(
        next(c for c in header.split("┃") if c.strip() == "robots"))] == "3"


def test_a_stack_of_one_robot_shows_no_robot_rows(tmp_path: Path) -> None:
    one = FLEET.split("robots:")[0] + 'edge: {ros_master: "http://127.0.0.1:11312"}\nnodes:' \
        + FLEET.split("nodes:")[1].replace("    serve: [arm1, arm3]\n", "")
    manifest, plan = _deploy(tmp_path, one)
    assert robot_status(plan) == []
    doc = json.loads(runner.invoke(app, ["status", str(manifest), "--json"]).output)
    assert "robots" not in doc
    shown = runner.invoke(app, ["status", str(manifest)], env=WIDE).output
    assert "robots (" not in shown
    listed = runner.invoke(app, ["ls"], env=WIDE).output
    assert "robots" not in listed and "lab-dev" in listed


def test_a_revoked_robot_and_a_hostile_edges_list(tmp_path: Path) -> None:
    """A robot the record keeps revoked says so; an edges list that is not fogiac's shows no robot, no traceback."""
    manifest, plan = _deploy(tmp_path)

    def revoke(document: dict[str, object]) -> None:
        edges = document[StackState.EDGES]
        assert isinstance(edges, list)
        edges[2] = {**edges[2], "revoked": True}

    StackState(plan.stack).update(revoke)
    shown = runner.invoke(app, ["status", str(manifest)], env=WIDE).output
    arm3 = next(line for line in shown.splitlines() if line.startswith("│ arm3 "))
    assert "revoked" in arm3
    StackState(plan.stack).set(StackState.EDGES, [{"name": "\x1b[31mred"}, 7, "x"])
    shown = runner.invoke(app, ["status", str(manifest)], env=WIDE)
    assert shown.exit_code == 0 and "Traceback" not in shown.output and "\x1b[31m" not in shown.output


def test_a_robot_revoked_by_the_verb_says_revoked(tmp_path: Path) -> None:
    """``fogiac robot revoke`` keeps the robot in the record's revoked list (``StackState.REVOKED``), not on its
    edge: status read only the edge's own flag, which nothing writes, and showed a revoked robot as a link down."""
    manifest, plan = _deploy(tmp_path)
    StackState(plan.stack).update(lambda document: document.__setitem__(StackState.REVOKED, ["arm3"]))  # as the verb
    rows = {row["robot"]: row for row in json.loads(runner.invoke(app, ["status", str(manifest), "--json"]).output)
            ["robots"]}
    assert {name: row["revoked"] for name, row in rows.items()} == {"arm1": False, "arm2": False, "arm3": True}
    shown = runner.invoke(app, ["status", str(manifest)], env=WIDE).output
    arm3 = next(line for line in shown.splitlines() if line.startswith("│ arm3 "))
    assert "revoked" in arm3


def test_odd_figures_in_a_robots_stats_are_unknown_not_trusted(tmp_path: Path) -> None:
    """A stats file with text, NaN or a string for connected (not what the relay writes) gives unknown figures,
    never a link up, a NaN in the JSON or a control character on the terminal."""
    _, plan = _deploy(tmp_path)
    folder = edge_dir(plan)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "relay-edge-planner@arm1.stats.json").write_text(json.dumps(
        {"connected": "yes", "rtt_ms": "fast", "refused": "many",
         "topics": [{"topic": "/a\x1b[31m", "direction": "out", "msgs": 1, "latency_ms": "x", "drops": "some"},
                    {"topic": "/c", "direction": "out", "msgs": "lots"},
                    {"topic": "/b", "direction": "in", "msgs": 3, "latency_ms": float("nan")}]}))
    (row, *_) = robot_status(plan)
    assert (row["links_up"], row["rtt_ms"], row["latency_ms"], row["sent"], row["served"], row["refused"],
            row["drops"]) == (0, None, None, 1, 3, 0, 0)
    assert json.loads(json.dumps(row, allow_nan=False))["links"][0]["connected"] is False
    out = StringIO()
    Console(file=out, width=250, color_system=None).print(robots_table([row]))
    assert "\x1b" not in out.getvalue() and "/a\\x1b[31m" in out.getvalue() and "down 0/2" in out.getvalue()


def test_a_link_its_cloud_end_refuses_says_why(tmp_path: Path) -> None:
    """A robot's edge end that a cloud end refuses (revoked, maybe from another machine: this record does not say
    so) writes the reason in its stats; the robot's row shows it beside the link, printable."""
    manifest, plan = _deploy(tmp_path)
    _stats(plan, "planner", "arm2", RelayStats("edge", False, None, 0.0, 0, (), link_refused="revoked"))
    _stats(plan, "grasp", "arm2", RelayStats("edge", False, None, 0.0, 0, (), link_refused="revoked\x1b[31m"))
    rows = {r["robot"]: r for r in robot_status(plan)}
    assert rows["arm2"]["link_refused"] == ["revoked", "revoked\x1b[31m"] and rows["arm1"]["link_refused"] == []
    shown = runner.invoke(app, ["status", str(manifest)], env=WIDE).output
    arm2 = next(line for line in shown.splitlines() if line.startswith("│ arm2 "))
    assert "down 0/2 (refused: revoked, revoked\\x1b[31m)" in arm2 and "\x1b" not in shown


def test_the_replies_a_robots_cloud_ends_routed_to_it(tmp_path: Path) -> None:
    """The shared nodes' replies each cloud end routed to the robot (its count, which the robot's edge end hears in
    the link's REPORT frames and writes as ``routed``) show beside its served count, summed over its links."""
    manifest, plan = _deploy(tmp_path)
    _stats(plan, "planner", "arm1", RelayStats("edge", True, 1.0, 0.0, 0, (_topic("/plan/path", "in", 6, 5.0),),
                                               routed={"served": 6, "undelivered": 0}))
    _stats(plan, "grasp", "arm1", RelayStats("edge", True, 1.0, 0.0, 0, (_topic("/grasp/reply", "in", 2, 5.0),),
                                             routed={"served": 3, "undelivered": 1}))
    _stats(plan, "planner", "arm2", RelayStats("edge", True, 1.0, 0.0, 0, (_topic("/plan/path", "in", 4, 5.0),),
                                               routed={"served": 4, "undelivered": 0}))
    rows = {r["robot"]: r for r in robot_status(plan)}
    assert rows["arm1"]["routed"] == {"served": 9, "undelivered": 1} and rows["arm1"]["served"] == 8
    assert rows["arm2"]["routed"] == {"served": 4, "undelivered": 0} and rows["arm3"]["routed"] is None
    shown = runner.invoke(app, ["status", str(manifest)], env=WIDE).output
    cells = {line.split("│")[1].strip(): [c.strip() for c in line.split("│")[2:-1]]
             for line in shown.splitlines() if line.startswith("│ arm")}
    assert cells["arm1"][5] == "8 (routed 9, lost 1)" and cells["arm2"][5] == "4 (routed 4)"
    assert cells["arm3"][5] == "0"
    doc = json.loads(runner.invoke(app, ["status", str(manifest), "--json"]).output)
    assert doc["robots"][0]["routed"] == {"served": 9, "undelivered": 1}
