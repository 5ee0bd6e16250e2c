"""AWS limits found at validate and plan, not at up (issue 26 item 14): the hosts subnet's addresses.

``vpc_cidr: 10.10.0.0/26`` gives the hosts a /27: 32 addresses, 5 of them AWS's, so 27 machines.
40 nodes passed validate and plan and failed when EC2 ran out of addresses, part-way through up.
(Tag counts and lengths are manifest cases in tests/badinput/manifests.)
"""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app

runner = CliRunner()


def _manifest(tmp_path: Path, *, nodes: int, vpc: str) -> Path:
    path = tmp_path / "fogiac.yaml"
    path.write_text(f"name: big\ncloud: {{provider: aws, region: us-west-2}}\nnetwork: {{vpc_cidr: {vpc}}}\nnodes:\n"
                    + "".join(f"  - {{name: n{i}, machine: t3.small, image: 'ros:noetic-ros-core'}}\n"
                              for i in range(nodes)))
    return path


@pytest.mark.parametrize("verb", ["validate", "plan"])
def test_a_hosts_subnet_too_small_is_refused(tmp_path: Path, _state_dir: Path, verb: str) -> None:
    result = runner.invoke(app, [verb, str(_manifest(tmp_path, nodes=40, vpc="10.10.0.0/26"))])
    assert result.exit_code == 1, result.output
    assert result.output.strip().splitlines() == [
        "error: network.vpc_cidr: 10.10.0.0/26 gives the hosts subnet 10.10.0.0/27, 27 usable addresses (AWS keeps "
        "5), for 40 machines; give vpc_cidr a shorter prefix (a /24 or wider)"]


def test_the_subnet_that_fits_passes(tmp_path: Path, _state_dir: Path) -> None:
    assert runner.invoke(app, ["validate", str(_manifest(tmp_path, nodes=27, vpc="10.10.0.0/26"))]).exit_code == 0
    assert runner.invoke(app, ["validate", str(_manifest(tmp_path, nodes=40, vpc="10.10.0.0/24"))]).exit_code == 0


def test_a_stack_of_more_nodes_than_a_hosts_subnet_holds_is_refused_before_placing_any(
        tmp_path: Path, _state_dir: Path) -> None:
    """Issue 26 item 24: plan of 1600 aws nodes took 15-25 s and 530 MB; now one line (~1 s, 55 MB)."""
    result = runner.invoke(app, ["plan", str(_manifest(tmp_path, nodes=1600, vpc="10.10.0.0/16"))])
    assert result.exit_code == 1, result.output
    assert result.output.strip().splitlines() == [
        f"{tmp_path / 'fogiac.yaml'}:4: nodes: 1600 nodes; a stack holds at most 250: split them into several "
        "manifests (or environments)"]
