"""Each host access reads back its own description, old records included, and answers for itself.

Why: the record keeps each host's access as a plain dict, and ``fogiac logs``, ``ssh``, ``status``
and ``down`` rebuild the access from it by asking the target that made it. There is no table of
access kinds and no ``isinstance`` on one: a record written before the ports left the access (its
``master_port``/``relay_port``) must still read, and a sandbox from such a record must still be
torn down.
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

import pytest

from fogiac.errors import ProvisionError
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.provision import LocalAccess, SshAccess, planned_ports, recorded_access, teardown
from fogiac.provision.local import local_access, local_ports
from fogiac.targets.hosts.target import HOSTS
from fogiac.targets.local.target import LOCAL
from tests.conftest import EXAMPLES, REPO

# provision.json host entries as fogiac wrote them before this change (5d5c9b4)
OLD_LOCAL = {"kind": "local", "sandbox": "/state/demo-dev/local/talker", "master_port": 40001, "relay_port": 40002,
             "python": "/usr/bin/python3", "base": "/state/demo-dev/local/talker", "nodes": ["talker"]}
OLD_SSH = {"kind": "ssh", "address": "198.51.100.7", "user": "ubuntu", "port": 2222, "key": "/keys/id_ed25519",
           "base_dir": None, "python": "python3", "master_port": 11311, "relay_port": 11411,
           "base": "/home/ubuntu/.fogiac/demo-dev/h0", "nodes": ["h0-node"]}


def test_an_old_local_record_reads_as_the_sandbox_it_was() -> None:
    access = LocalAccess.from_description(OLD_LOCAL)
    assert access.sandbox == Path("/state/demo-dev/local/talker") and access.python == "/usr/bin/python3"
    assert access.location == "127.0.0.1:40002"  # what the edge dialed: the record's relay port
    assert LocalAccess.from_description(access.describe()) == access
    assert access.shell_argv(base=OLD_LOCAL["base"], known_hosts=Path("/kh")) == (
        ["bash", "--rcfile", "/state/demo-dev/local/talker/env/ros.sh", "-i"], "/state/demo-dev/local/talker")
    assert access.follow_argv("tail -f x.log", known_hosts=Path("/kh")) == ["bash", "-c", "tail -f x.log"]


def test_an_old_ssh_record_reads_without_its_ports() -> None:
    access = SshAccess.from_description(OLD_SSH)
    assert access == SshAccess(address="198.51.100.7", user="ubuntu", key=Path("/keys/id_ed25519"), port=2222)
    assert "relay_port" not in access.describe() and "master_port" not in access.describe()
    assert SshAccess.from_description(access.describe()) == access
    ssh = ["ssh", "-i", "/keys/id_ed25519", "-p", "2222", "-o", "IdentitiesOnly=yes", "-o",
           "UserKnownHostsFile=/kh", "-o", "StrictHostKeyChecking=yes", "ubuntu@198.51.100.7"]
    assert access.follow_argv("tail -f x.log", known_hosts=Path("/kh")) == [*ssh, "tail -f x.log"]
    argv, _ = access.shell_argv(base="/home/ubuntu/.fogiac/demo-dev/h0", known_hosts=Path("/kh"))
    assert argv == [ssh[0], "-t", *ssh[1:], "cd /home/ubuntu/.fogiac/demo-dev/h0 && exec $SHELL -l"]


def test_a_description_of_another_kind_is_refused_in_one_line() -> None:
    with pytest.raises(ProvisionError, match=r"^recorded host access of kind 'ssh' is not 'local'$"):
        LocalAccess.from_description(OLD_SSH)
    with pytest.raises(ProvisionError, match=r"^recorded host access of kind 'pod' is not 'ssh'$"):
        SshAccess.from_description({"kind": "pod"})


def test_each_target_reads_back_what_it_recorded(tmp_path: Path) -> None:
    (tmp_path / "provision.json").write_text(json.dumps({"hosts": {"talker": OLD_LOCAL}}))
    ((name, (access, base, nodes)),) = recorded_access(tmp_path, LOCAL.access_from).items()
    assert (name, base, nodes) == ("talker", OLD_LOCAL["base"], ("talker",)) and isinstance(access, LocalAccess)
    (tmp_path / "provision.json").write_text(json.dumps({"hosts": {"h0": OLD_SSH}}))
    ((_, (access, _, _)),) = recorded_access(tmp_path, HOSTS.access_from).items()
    assert access.location == "198.51.100.7:2222"
    with pytest.raises(ProvisionError, match="is not 'local'"):
        recorded_access(tmp_path, LOCAL.access_from)


def test_a_sandbox_from_an_old_record_is_torn_down(tmp_path: Path) -> None:
    plan = compile_plan(load_manifest(EXAMPLES / "minimal.yaml"), target="local")
    (spec,) = plan.hosts
    sandbox = tmp_path / "local" / spec.name
    (sandbox / "run").mkdir(parents=True)
    entry = {**OLD_LOCAL, "sandbox": str(sandbox), "base": str(sandbox), "nodes": list(spec.nodes)}
    (tmp_path / "provision.json").write_text(json.dumps({"hosts": {spec.name: entry}}))
    hosts = {name: found[0] for name, found in recorded_access(tmp_path, LOCAL.access_from).items()}
    report = teardown(plan, hosts=hosts, state_dir=tmp_path)
    assert report.ok, report
    assert not sandbox.exists() and not (tmp_path / "provision.json").exists()


def test_the_ports_are_the_targets_word_beside_the_access(tmp_path: Path) -> None:
    plan = compile_plan(load_manifest(EXAMPLES / "minimal.yaml"), target="local")
    (spec,) = plan.hosts
    ports = local_ports(plan, state_dir=tmp_path)
    assert ports == local_ports(plan, state_dir=tmp_path)  # chosen once, kept
    assert ports[spec.name].relay_port == int(local_access(plan, state_dir=tmp_path)[spec.name].location.split(":")[1])
    routed = compile_plan(load_manifest(EXAMPLES / "ros2-zenoh.yaml"))
    assert {h: p.relay_port for h, p in planned_ports(routed).items()} == {r.host: r.port for r in routed.routes}


def test_no_isinstance_on_an_access_kind_and_no_table_of_kinds() -> None:
    found = []
    for path in sorted((REPO / "fogiac").rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and ast.unparse(node.func) == "isinstance" and len(node.args) == 2 \
                    and "Access" in ast.unparse(node.args[1]):
                found.append(f"{path.relative_to(REPO)}:{node.lineno}: {ast.unparse(node)}")
            if isinstance(node, ast.Name) and node.id in ("ACCESS_KINDS", "access_from_dict"):
                found.append(f"{path.relative_to(REPO)}:{node.lineno}: {node.id}")
    assert found == []
