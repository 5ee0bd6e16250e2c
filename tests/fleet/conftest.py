"""The fleet tests run on the relay tests' real roscores and lab certificates."""

from pathlib import Path

import pytest

from tests.fleet.fleet_support import fleet_folder
from tests.net.relay.conftest import certs, masters, procs, ros_ready

__all__ = ["certs", "fleet_certs", "masters", "procs", "ros_ready"]


@pytest.fixture
def fleet_certs(certs: Path, tmp_path: Path) -> Path:
    """The lab folder with each robot's own pair and the access file (every robot, the shared plan topics)."""
    return fleet_folder(certs, tmp_path / "certs")
