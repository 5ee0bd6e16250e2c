"""Issue 26 items 4 and 5: a value in a manifest (a tag, a command) can neither forge the pull-request
comment (close its code fence, add headings, raw HTML, a ``<!--`` that hides the rest) nor drive the
terminal (colour, OSC 8 links, cursor moves, bidirectional reordering) in ``plan`` and ``up``."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.cli.deploy import _show
from fogiac.manifest.schema import parse_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.document import plan_document
from fogiac.plan.review import md_code, visible

runner = CliRunner()

BASE = """\
name: review
cloud: {provider: aws, region: us-west-2}
network: {mode: vpn, vpc_cidr: 10.10.0.0/16, ssh_from: [10.1.2.3/32]}
nodes:
  - name: planner
    machine: c5.large
    image: ros:noetic-ros-core
    command: [rosrun, planner, planner]
"""
HOSTILE = BASE.replace("nodes:\n", 'tags: {owner: "x\\n```\\n\\n## Approved by security <!--", '
                       'team: "\\e[2K\\e]8;;http://evil\\e\\\\click\\e]8;;\\e\\\\ \\u202eevil\\u202c", '
                       'note: "````` <b>bold</b> [link](http://x) ~~~"}\nnodes:\n').replace(
    "planner, planner]", 'planner, "planner\\n```\\n<img src=x onerror=alert(1)>\\r\\x9b2J"]') + (
    '  - name: probe\n    machine: t3.small\n    command: [echo, "\\e[2K\\e]8;;http://evil\\e\\\\x\\u202e"]\n')
FORBIDDEN = re.compile("[\x00-\x09\x0b-\x1f\x7f-\x9f\u061c\u200b-\u200f\u2028-\u202e\u2060-\u2069\ufeff]")


def _structure(markdown: str) -> list[str]:
    """The lines outside fenced code blocks, as CommonMark reads the fences."""
    outside, fence = [], ""
    for line in markdown.splitlines():
        stripped = line.lstrip(" ")
        if fence:
            if len(line) - len(stripped) <= 3 and re.fullmatch(rf"{fence}`*\s*", stripped):
                fence = ""
        elif match := re.match(r"(`{3,}|~{3,})", stripped):
            fence = match.group(1)
        else:
            outside.append(line)
    assert not fence, "a code block is left open"
    return outside


@pytest.fixture
def pair(tmp_path: Path) -> tuple[str, str]:
    (tmp_path / "base.yaml").write_text(BASE)
    (tmp_path / "head.yaml").write_text(HOSTILE)
    return str(tmp_path / "head.yaml"), str(tmp_path / "base.yaml")


def test_values_cannot_forge_the_pull_request_comment(pair: tuple[str, str]) -> None:
    head, base = pair
    result = runner.invoke(app, ["plan", head, "--against", base, "--markdown"])
    assert result.exit_code == 0, result.output
    assert not FORBIDDEN.search(result.output)
    outside = _structure(result.output)
    headings = [line for line in outside if line.startswith("#")]
    assert headings[0].startswith("### fogiac plan: ")
    assert all(re.fullmatch(r"#### [a-z ()]+", line) for line in headings[1:]), headings
    own = ("<details><summary>", "</details>")  # the comment's own folding, around long sections
    assert not any(("<" in line and not line.startswith(own)) or "Approved" in line or "onerror" in line
                   for line in outside), outside
    # the values are there, whole and visibly escaped, inside the code blocks
    assert "    tags.owner: null -> x\\n```\\n\\n## Approved by security <!--" in result.output.splitlines()
    assert "\\e]8;;http://evil\\e\\click" in result.output and "\\u202eevil\\u202c" in result.output


def test_values_reach_the_terminal_visibly_escaped_in_plan(pair: tuple[str, str]) -> None:
    head, base = pair
    for args in (["plan", head, "--against", base], ["plan", head]):
        result = runner.invoke(app, args)
        assert result.exit_code == 0, result.output
        assert not FORBIDDEN.search(result.output), [line for line in result.output.splitlines()
                                                     if FORBIDDEN.search(line)][:3]
        assert "\\e[2K\\e]8;;http://evil" in result.output


def test_up_shows_the_plan_with_values_escaped(pair: tuple[str, str], capsys: pytest.CaptureFixture[str]) -> None:
    head, _ = pair
    plan = compile_plan(parse_manifest(Path(head).read_text(), base=Path(head).parent))
    doc = plan_document(plan, [{"stack": "compute", "type": "aws:ec2/instance:Instance", "name": "i\x1b[2J",
                                "inputs": {}}], manifest=Path(head))
    _show(doc, ("preflight: ok \x1b[1A\x1b[2Kinjected",))
    _show(doc, None)
    out = capsys.readouterr().out
    assert not FORBIDDEN.search(out)
    assert "preflight: ok \\e[1A\\e[2Kinjected" in out and "echo '\\e[2K\\e]8;;http://evil" in out


def test_visible_and_code_spans() -> None:
    assert visible("a\tb\x1b[31m\x9b\u202e\u200b") == "a\\tb\\e[31m\\x9b\\u202e\\u200b"
    assert md_code("a`b") == "``a`b``" and md_code("`x") == "`` `x ``"


def test_up_report_shows_a_hosts_error_escaped(capsys: pytest.CaptureFixture[str]) -> None:
    from fogiac.provision.report import report_table
    from fogiac.provision.runner import HostOutcome, ProvisionReport
    from fogiac.tables import console

    failed = HostOutcome(host="h0", address="10.0.0.1", steps=(), error="h0: `x` failed (\x1b]8;;http://evil\x1b\\"
                         "[bold]click[/bold]\u202e)", files_pushed=0, bytes_sent=0, seconds=1.0)
    console().print(report_table(ProvisionReport(hosts=(failed,), seconds=1.0)))
    out = capsys.readouterr().out
    assert not FORBIDDEN.search(out)
    assert "\\e]8;;http://evil\\e\\[bold]click[/bold]\\u202e" in out
