"""Issue 26 items 6 and 33: what the plan document and the pull-request comment must say.

Item 6: settings the plan never showed (SSH user, key and port, cloud.runtime, the requirements file,
relay compression and queue size, autostop) are in the document and in the diff; a weakened autostop is
flagged as a cost change, and the plan says the autostop in force beside the monthly figure.
Item 33: the comment's header (target, region, fogiac version, "(new stack)"), the month beside the
hour, replacements and a shutdown that now deletes said in words, actuation topics flagged first, long
lists folded."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac import __version__
from fogiac.cli import app

runner = CliRunner()

HOSTS = """\
name: lab
cloud:
  provider: hosts
  runtime: native
  hosts:
    - {{name: h0, address: 10.232.0.2, user: alice, key: key, port: 22}}
{autostop}relay: {{compression: none, queue_size: 2}}
nodes:
  - name: arm
    machine: t3.small
    host: h0
    launch: {{package: fogtest, file: talker.launch, workspace: ws, requirements: ws/requirements.txt}}
"""
AWS = """\
name: review
cloud: {{provider: aws, region: us-west-2{autostop}}}
network: {{mode: vpn, vpc_cidr: 10.10.0.0/16, ssh_from: [10.1.2.3/32]}}
nodes:
  - name: planner
    machine: c5.large
    workload: motion_planning
    topics: {{in: [/req], out: [/path]}}
"""


def _pair(tmp_path: Path, base: str, head: str, *args: str) -> list[str]:
    (tmp_path / "ws" / "src").mkdir(parents=True, exist_ok=True)
    (tmp_path / "ws" / "requirements.txt").write_text("numpy\n")
    (tmp_path / "key").write_text("not read\n")
    (tmp_path / "base.yaml").write_text(base)
    (tmp_path / "head.yaml").write_text(head)
    result = runner.invoke(app, ["plan", str(tmp_path / "head.yaml"), "--against", str(tmp_path / "base.yaml"),
                                 "--detailed-exitcode", *args])
    assert result.exit_code == 2, result.output
    return [line.strip() for line in result.output.splitlines()]


@pytest.mark.parametrize(("change", "expect"), [
    (("user: alice", "user: root"), "ssh: {user=alice, key=KEY, port=22} -> {user=root, key=KEY, port=22}"),
    (("port: 22", "port: 2222"), "ssh: {user=alice, key=KEY, port=22} -> {user=alice, key=KEY, port=2222}"),
    (("runtime: native", "runtime: container"), "runtime: native -> container"),
    (("compression: none", "compression: zstd"), "~ relay: {compression={*=none}, queue_size=2} -> "
                                                  "{compression={*=zstd}, queue_size=2}"),
    (("queue_size: 2", "queue_size: 500"), "~ relay: {compression={*=none}, queue_size=2} -> "
                                            "{compression={*=none}, queue_size=500}"),
    (("requirements: ws/requirements.txt", "requirements: ws/other.txt"), "~ arm requirements"),
])
def test_settings_the_plan_never_showed_now_show(change: tuple[str, str], expect: str, tmp_path: Path) -> None:
    (tmp_path / "ws").mkdir()
    (tmp_path / "ws" / "other.txt").write_text("scipy\n")
    base = HOSTS.format(autostop="")
    lines = _pair(tmp_path, base, base.replace(*change))
    assert expect.replace("KEY", str(tmp_path / "key")) in lines, "\n".join(lines)


def test_a_changed_requirements_file_shows_by_its_digest(tmp_path: Path) -> None:
    base = HOSTS.format(autostop="")
    (tmp_path / "ws" / "src").mkdir(parents=True)
    (tmp_path / "ws" / "requirements.txt").write_text("numpy\n")
    (tmp_path / "key").write_text("not read\n")
    (tmp_path / "m.yaml").write_text(base)
    before = runner.invoke(app, ["plan", str(tmp_path / "m.yaml"), "--json"]).output
    (tmp_path / "ws" / "requirements.txt").write_text("numpy\nevil-package\n")
    after = runner.invoke(app, ["plan", str(tmp_path / "m.yaml"), "--json"]).output
    assert before != after and '"what": "requirements"' in after


@pytest.mark.parametrize(("base", "head", "flag"), [
    ("", ", autostop: {idle_minutes: 600}", "! autostop waits longer: 30 -> 600 idle minutes"),
    ("", ", autostop: off", "! autostop turned off: was stops the hosts after 30 idle minutes; now the hosts run "
                            "until `fogiac down`"),
])
def test_a_weakened_autostop_is_flagged_as_a_cost_change(base: str, head: str, flag: str, tmp_path: Path) -> None:
    lines = _pair(tmp_path, AWS.format(autostop=base), AWS.format(autostop=head))
    assert "cost while idle raised:" in lines and flag in lines, "\n".join(lines)
    comment = _pair(tmp_path, AWS.format(autostop=base), AWS.format(autostop=head), "--markdown")
    assert "> **Cost while idle raised**" in comment and f"> - {flag[2:]}".replace("`", "\\`") in comment


def test_a_shorter_autostop_is_no_cost_flag(tmp_path: Path) -> None:
    lines = _pair(tmp_path, AWS.format(autostop=""), AWS.format(autostop=", autostop: {idle_minutes: 10}"))
    assert "cost while idle raised:" not in lines
    assert "~ autostop: {idle_minutes=30.0, action=stop, power=machine} -> {idle_minutes=10.0, action=stop, " \
           "power=machine}" in lines


def test_plan_says_the_autostop_beside_the_month(tmp_path: Path) -> None:
    (tmp_path / "m.yaml").write_text(AWS.format(autostop=""))
    lines = runner.invoke(app, ["plan", str(tmp_path / "m.yaml")]).output.splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith("cost: $"))
    assert lines[at + 1] == "  autostop stops the hosts after 30 idle minutes"
    (tmp_path / "m.yaml").write_text(AWS.format(autostop=", autostop: off"))
    output = runner.invoke(app, ["plan", str(tmp_path / "m.yaml")]).output
    assert "  autostop off: the hosts run (and cost) until `fogiac down`" in output.splitlines()


def test_the_comment_header_says_target_region_version_and_new_stack(tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "state"))
    (tmp_path / "m.yaml").write_text(AWS.format(autostop=""))
    lines = runner.invoke(app, ["plan", str(tmp_path / "m.yaml"), "--markdown"]).output.splitlines()
    assert lines[0] == "### fogiac plan: `review-dev` (new stack)"
    assert lines[1] == f"target `aws` · region `us-west-2` · fogiac `{__version__}`"
    assert lines[4] == "hourly cost: $0.0000 -> $0.2350 (+$0.2350)  "
    assert lines[5] == ("monthly cost if left running (730 h): $0.00 -> $171.55 (+$171.55); autostop stops the hosts "
                        "after 30 idle minutes")
    assert "<details><summary>resources (" in "\n".join(lines)  # a new stack's 30 resources: folded


def test_replacement_and_a_deleting_shutdown_are_said_in_words(tmp_path: Path) -> None:
    base = AWS.format(autostop="")
    head = AWS.format(autostop=", autostop: {action: terminate}").replace("10.10.0.0/16", "10.20.0.0/16")
    lines = _pair(tmp_path, base, head, "--markdown")
    assert "> [!CAUTION]" in lines and "> **What this does**" in lines
    assert any(line.startswith("> - review-dev-vpc (Vpc) is replaced, not updated (cidrBlock changed): it is "
                               "deleted and a new one created with new ids; for a machine that is downtime")
               for line in lines), "\n".join(lines)
    assert any("shutdown behaviour stop -> terminate: a shutdown (autostop's included) now deletes the machine "
               "and its disk" in line for line in lines), "\n".join(lines)
    assert ("> - autostop now terminates the hosts: an idle stack is deleted with its disks, not stopped"
            in lines)


def test_an_actuation_topic_is_flagged_above_the_others(tmp_path: Path) -> None:
    base = AWS.format(autostop="")
    lines = _pair(tmp_path, base, base.replace("out: [/path]", "out: [/path, /map, /base/cmd_vel]"), "--markdown")
    flags = [line for line in lines if line.startswith("> - ")]
    assert flags[0].startswith("> - actuation topic added cloud -> robot: /base/cmd\\_vel (host planner)")
    assert flags[1].startswith("> - topic added cloud -> edge: /map")
