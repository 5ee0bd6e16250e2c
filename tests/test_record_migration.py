"""One stack record (issue 32): a stack folder written by an older fogiac (four files) is read as one record,
``status`` and ``down`` work on it, and its first write leaves the one record file; the store's
compare-and-swap refuses a writer that read an older version; a corrupt section is one line naming the file.

The older folder is ``tests/data/legacy-stack/`` (see its README): the files fogiac at 5d5c9b4 wrote for a
local ``up`` of examples/motion-planning.yaml.
"""

from __future__ import annotations

import json
import os
import shutil
import stat
import sys
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from fogiac import deployment, targets
from fogiac.cli import app
from fogiac.lifecycle.edge import recorded_edge
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.procs import free_port
from fogiac.provision import recorded_access
from fogiac.provision.local import PORTS_FILE, sandbox_root
from fogiac.state import FORMAT_VERSION, LEGACY_FILES, StackState, StaleRecord, read_json
from fogiac.store import FolderStore
from tests.conftest import EXAMPLES
from tests.support.procs import alive_pids

LEGACY = Path(__file__).resolve().parent / "data" / "legacy-stack" / "motion-planning-dev"
STACK = "motion-planning-dev"
runner = CliRunner()


def cli(*args: str) -> tuple[int, str]:
    result = runner.invoke(app, list(args), env={"COLUMNS": "200"})
    return result.exit_code, result.output


def _manifest(folder: Path, edge_port: int) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "fogiac.yaml"
    path.write_text((EXAMPLES / "motion-planning.yaml").read_text().replace(
        "ros_master: http://localhost:11311", f"ros_master: http://127.0.0.1:{edge_port}"))
    return path


def write_legacy(folder: Path, **values: object) -> dict[str, Any]:
    """The older fogiac's four files in ``folder``, placeholders filled; returns each file's JSON."""
    folder.mkdir(parents=True, exist_ok=True, mode=0o700)
    written = {}
    for name in LEGACY_FILES.values():
        text = (LEGACY / name).read_text()
        for key, value in values.items():
            text = text.replace(f"@{key}@", str(value))
        assert "@" not in text, f"{name}: a placeholder is left"
        (folder / name).write_text(text)
        os.chmod(folder / name, 0o600)
        written[name] = json.loads(text)
    return written


def _values(folder: Path, manifest: Path, *, edge: int = 40001, master: int = 40002, relay: int = 40003,
            since: str = "2026-11-28T01:56:05Z", since_epoch: float = 1795830965.726683,
            python: str = sys.executable) -> dict[str, object]:
    return {"STACK_FOLDER": folder, "MANIFEST": manifest.resolve(), "PYTHON": python, "EDGE_PORT": edge,
            "MASTER_PORT": master, "RELAY_PORT": relay, "SINCE": since, "SINCE_EPOCH": since_epoch}


def _json_files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.suffix == ".json")


@pytest.fixture
def legacy(tmp_path: Path, _state_dir: Path) -> tuple[Path, Path, dict[str, Any]]:
    """A stack folder as the older fogiac left it after a complete local up (nothing runs)."""
    manifest = _manifest(tmp_path / "checkout", 40001)
    folder = _state_dir / STACK
    return manifest, folder, write_legacy(folder, **_values(folder, manifest))


def test_an_older_folder_is_read_as_one_record_without_writing(legacy: tuple[Path, Path, dict[str, Any]]) -> None:
    manifest, folder, files = legacy
    record = deployment.read(STACK)
    assert record == deployment.Deployment(**files["stack.json"])
    assert record is not None and record.state == deployment.COMPLETE and record.target == "local"
    assert deployment.read_applied(STACK) == files["applied.json"]
    hosts = recorded_access(folder, targets.get("local").access_from)
    assert list(hosts) == ["planner"]
    assert hosts["planner"][1:] == (f"{folder}/local/planner", ("planner",))
    older = files["provision.json"]["hosts"]["planner"]  # ports were the access's then: the relay's is where the edge dials
    assert hosts["planner"][0].describe() == {"kind": older["kind"], "sandbox": older["sandbox"],
                                              "python": older["python"], "location": f"127.0.0.1:{older['relay_port']}"}
    plan = compile_plan(load_manifest(manifest), target="local")
    assert recorded_edge(plan) == {"name": STACK, **files["deployment.json"]}
    code, out = cli("ls")
    assert code == 0 and any(STACK in line and "local" in line and " up " in line for line in out.splitlines()), out
    assert _json_files(folder) == sorted(LEGACY_FILES.values())  # reading wrote nothing


def test_the_first_write_migrates_to_the_one_record(legacy: tuple[Path, Path, dict[str, Any]]) -> None:
    _, folder, files = legacy
    deployment.cut_back(STACK)  # a write of one section
    assert _json_files(folder) == [StackState.RECORD]
    assert stat.S_IMODE((folder / StackState.RECORD).stat().st_mode) == 0o600
    doc = json.loads((folder / StackState.RECORD).read_text())
    assert doc["format_version"] == FORMAT_VERSION and doc["serial"] == 1 and doc["stack"] == STACK
    assert doc["deployment"] == {**files["stack.json"], "state": deployment.PARTIAL, "plan_digest": "",
                                 "manifest_digest": ""}
    assert doc["applied"] == files["applied.json"]
    assert doc["edges"] == [{"name": STACK, **files["deployment.json"]}]
    assert doc["hosts"] == files["provision.json"]["hosts"]
    # a crash between writing the record and removing the four files: the record is what is read,
    # and the next write removes what was left
    (folder / "stack.json").write_text(json.dumps({**files["stack.json"], "target": "aws"}))
    assert deployment.read(STACK).target == "local"  # type: ignore[union-attr]
    deployment.removed(STACK)
    assert _json_files(folder) == [StackState.RECORD]
    again = json.loads((folder / StackState.RECORD).read_text())
    assert again["serial"] == 2 and again["lineage"] == doc["lineage"]
    assert deployment.read(STACK).state == deployment.REMOVED  # type: ignore[union-attr]


def test_a_writer_that_read_an_older_version_is_refused(tmp_path: Path) -> None:
    store = FolderStore(tmp_path)
    assert store.get("robot-dev").document is None and store.get("robot-dev").version is None
    v = FORMAT_VERSION
    first = store.put("robot-dev", {"format_version": v, "a": 1}, expected=None)
    with pytest.raises(StaleRecord, match="changed since it was read"):
        store.put("robot-dev", {"format_version": v, "a": 2}, expected=None)  # create-only: a record is there
    second = store.put("robot-dev", {"format_version": v, "a": 2}, expected=first)
    with pytest.raises(StaleRecord):
        store.put("robot-dev", {"format_version": v, "a": 3}, expected=first)  # another writer came between
    assert store.get("robot-dev").document == {"format_version": v, "a": 2}
    assert store.get("robot-dev").version == second
    # two StackStates of one stack, interleaved: the second put is refused, the first one's write stays
    one, two = StackState("robot-dev", store=store), StackState("robot-dev", store=store)
    one.set(StackState.HOSTS, {})
    read = two.snapshot()
    one.set(StackState.HOSTS, {"h0": {"kind": "x"}})
    with pytest.raises(StaleRecord):
        store.put("robot-dev", {**(read.document or {}), "hosts": {"h1": {}}}, expected=read.version)
    assert two.get(StackState.HOSTS) == {"h0": {"kind": "x"}}


def test_an_older_folder_changed_since_it_was_read_is_not_migrated(legacy: tuple[Path, Path, dict[str, Any]]) -> None:
    _, folder, files = legacy
    state = StackState(STACK)
    read = state.snapshot()
    (folder / "stack.json").write_text(json.dumps({**files["stack.json"], "state": "removed"}))
    with pytest.raises(StaleRecord):
        state.store.put(STACK, {**(read.document or {}), "format_version": FORMAT_VERSION}, expected=read.version)
    assert _json_files(folder) == sorted(LEGACY_FILES.values())  # nothing written, nothing removed
    assert deployment.read(STACK).state == deployment.REMOVED  # type: ignore[union-attr]


@pytest.fixture
def recorded(tmp_path: Path, _state_dir: Path) -> tuple[Path, StackState]:
    """minimal.yaml with a record as a complete local up writes it (one file), and `plan` agreeing."""
    manifest = tmp_path / "fogiac.yaml"
    shutil.copy(EXAMPLES / "minimal.yaml", manifest)
    code, out = cli("plan", str(manifest), "--json", "--target", "local")
    assert code == 0, out
    applied = json.loads(out)
    deployment.finish(compile_plan(load_manifest(manifest), target="local"), manifest,
                      plan_digest=applied["plan_digest"], applied=applied)
    assert _json_files(_state_dir / "minimal-dev") == [StackState.RECORD]
    assert cli("plan", str(manifest), "--detailed-exitcode")[0] == 0  # the good record: no changes
    return manifest, StackState("minimal-dev")


def _one_line_error(code: int, out: str, needle: str) -> None:
    assert code == 1, out
    assert "Traceback" not in out and len(out.strip().splitlines()) == 1, out
    assert needle in out, out


def test_a_corrupt_section_is_one_line_naming_the_record(recorded: tuple[Path, StackState]) -> None:
    manifest, state = recorded
    good = state.get(StackState.DEPLOYMENT)
    state.set(StackState.DEPLOYMENT, {**good, "state": "gone"})
    for verb in (("plan", str(manifest), "--detailed-exitcode"), ("status", str(manifest))):
        _one_line_error(*cli(*verb), f"{StackState.RECORD} (section deployment): not a fogiac deployment record "
                                     "(state 'gone')")
    state.set(StackState.DEPLOYMENT, good)
    applied = state.get(StackState.APPLIED)
    state.set(StackState.APPLIED, {**applied, "hosts": 5})
    _one_line_error(*cli("plan", str(manifest), "--detailed-exitcode"),
                    f"{StackState.RECORD} (section applied): not a plan document fogiac applied")


def test_a_record_that_is_not_one_is_one_line(recorded: tuple[Path, StackState]) -> None:
    manifest, state = recorded
    path = state.folder / StackState.RECORD
    doc = json.loads(path.read_text())
    for bad, needle in (({**doc, "format_version": FORMAT_VERSION + 1}, "written by a newer fogiac"),
                        ({k: v for k, v in doc.items() if k != "format_version"},
                         "not a fogiac stack record (format_version is missing)"),
                        ([doc], "not a fogiac stack record (a JSON list)")):
        path.write_text(json.dumps(bad))
        _one_line_error(*cli("status", str(manifest)), f"{path}: {needle}")


def _facts(doc: dict[str, Any]) -> dict[str, Any]:
    """What `status --json` says that the record decides (not the uptime, not the traffic)."""
    return {"deployed": doc["deployed"], "partial": doc["partial"], "edge_master": doc["edge_master"],
            "hosts": [(h["host"], h["address"], [(n["node"], n.get("running")) for n in h["nodes"]])
                      for h in doc["hosts"]],
            "relays": [(r["host"], r["connect"]) for r in doc["relays"]],
            "edge": sorted(e["name"] for e in doc["edge"])}


@pytest.mark.ros
@pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)")
def test_status_and_down_work_on_a_running_stack_with_an_older_folder(
        tmp_path: Path, _state_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Up with this fogiac, then its record put back as the older fogiac wrote it for the same deployment:
    status says the same, down stops every process, and the folder is left with the one record."""
    home = tmp_path / "home"  # the edge master's logs stay out of the operator's ~/.ros
    home.mkdir()
    monkeypatch.setenv("HOME", str(home))
    edge = free_port()
    manifest = _manifest(tmp_path / "checkout", edge)
    folder = _state_dir / STACK
    code, out = cli("up", str(manifest), "--target", "local", "--yes", "--start-edge-master")
    try:
        assert code == 0, out
        doc = json.loads((folder / StackState.RECORD).read_text())
        host = doc["hosts"]["planner"]
        since = doc["deployment"]
        ports = read_json(sandbox_root(folder) / PORTS_FILE)["planner"]  # the older fogiac kept them in the access
        files = write_legacy(folder, **_values(folder, manifest, edge=edge, master=ports["master"],
                                               relay=ports["relay"], since=since["since"],
                                               since_epoch=since["since_epoch"], python=host["python"]))
        # the older fogiac's files say what this fogiac's sections say (less what the record adds, and with
        # the ports where the access kept them then: the relay's is the address the edge dials)
        older = files["provision.json"]["hosts"]["planner"]
        assert host["location"] == f"127.0.0.1:{older['relay_port']}"
        assert {k: v for k, v in older.items() if k not in ("master_port", "relay_port")} == \
            {k: v for k, v in host.items() if k != "location"}
        assert [{"name": STACK, **files["deployment.json"]}] == doc["edges"]
        # (the digests: of this run's manifest and plan, whose edge port the fixture's were not made with)
        assert {**files["stack.json"], "manifest_digest": since["manifest_digest"],
                "plan_digest": since["plan_digest"]} == doc["deployment"]
        code, out = cli("status", str(manifest), "--json")
        assert code == 0, out
        now = _facts(json.loads(out))
        relay = host["location"]
        assert now["deployed"] and not now["partial"] and now["hosts"] == [("planner", relay, [("planner", True)])]
        assert now["relays"] == [("planner", relay)], now
        (folder / StackState.RECORD).unlink()  # the folder now is as the older fogiac left it
        assert _json_files(folder) == sorted(LEGACY_FILES.values())
        code, out = cli("status", str(manifest), "--json")
        assert code == 0, out
        assert _facts(json.loads(out)) == now
        assert _json_files(folder) == sorted(LEGACY_FILES.values())  # status wrote nothing
    finally:
        code, out = cli("down", str(manifest), "--yes")
    assert code == 0, out
    assert "nothing left" in out.splitlines()[-1], out
    assert alive_pids(_state_dir) == []
    assert _json_files(folder) == [StackState.RECORD]  # migrated by down's write, the four files gone
    assert deployment.read(STACK).state == deployment.REMOVED  # type: ignore[union-attr]
    assert recorded_access(folder, targets.get("local").access_from) == {}
    assert StackState(STACK).section_names() == {StackState.DEPLOYMENT}
    assert cli("status", str(manifest))[1].splitlines() == [f"{STACK}: not deployed"]
