"""``fogiac vpn`` without a tunnel: picking the profile, idempotent down, the root message."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
MINIMAL = REPO / "examples" / "minimal.yaml"


def fogiac(*args: str, state: Path, prefix: tuple[str, ...] = ()) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "FOGIAC_STATE_DIR": str(state),
           "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    return subprocess.run([*prefix, sys.executable, "-m", "fogiac", *args], env=env, cwd="/",
                          capture_output=True, text=True, timeout=60)


def test_status_and_down_with_the_manifests_stack(tmp_path: Path) -> None:
    if not MINIMAL.exists():
        pytest.skip("examples/minimal.yaml is not there")
    status = fogiac("vpn", "status", str(MINIMAL), state=tmp_path)
    assert (status.returncode, status.stdout, status.stderr) == (0, "VPN stopped\n", "")
    down = fogiac("vpn", "down", str(MINIMAL), "--env", "prod", state=tmp_path)
    assert (down.returncode, down.stdout) == (0, "VPN not running\n")
    assert not tmp_path.joinpath("minimal-prod").exists()  # looking does not create state


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root: only root gets past the root check to the profile lookup")
def test_up_without_a_profile_names_where_it_looked(tmp_path: Path) -> None:
    missing = tmp_path / "edge" / "client.ovpn"
    up = fogiac("vpn", "up", "--profile", str(missing), state=tmp_path)
    assert (up.returncode, up.stdout) == (1, "")
    assert up.stderr == f"error: no VPN profile at {missing}; write one first (fogiac up in vpn mode)\n"


def _unprivileged() -> tuple[str, ...] | None:
    if os.geteuid() != 0:
        return ()
    setpriv = shutil.which("setpriv")
    return (setpriv, "--reuid=65534", "--regid=65534", "--clear-groups") if setpriv else None


def test_up_says_root_is_needed(tmp_path: Path) -> None:
    prefix = _unprivileged()
    if prefix is None:
        pytest.skip("running as root and no setpriv (util-linux) to drop privileges")
    up = fogiac("vpn", "up", "--profile", str(tmp_path / "client.ovpn"), state=tmp_path, prefix=prefix)
    assert (up.returncode, up.stdout) == (1, "")
    assert up.stderr == ("error: `fogiac vpn up` needs root: OpenVPN creates a tun device and sets "
                         "routes (run it with sudo)\n")


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root: only root gets past the root check to the profile lookup")
def test_a_fleets_robot_has_its_own_profile(tmp_path: Path) -> None:
    """Issue 34 on aws: ``--robot NAME`` runs the robot's own profile (``vpn-NAME/client.ovpn`` of the stack)."""
    if not MINIMAL.exists():
        pytest.skip("examples/minimal.yaml is not there")
    up = fogiac("vpn", "up", str(MINIMAL), "--robot", "arm1", state=tmp_path)
    where = tmp_path / "minimal-dev" / "vpn-arm1" / "client.ovpn"
    assert (up.returncode, up.stderr) == (1, f"error: no VPN profile at {where}; write one first (fogiac up in vpn "
                                             "mode)\n")
    status = fogiac("vpn", "status", str(MINIMAL), "--robot", "arm1", state=tmp_path)
    assert (status.returncode, status.stdout) == (0, "VPN stopped\n")
