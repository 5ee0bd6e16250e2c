"""Issue 34, ROS 1: a revoked robot's edge end is told why the cloud end refuses it, and backs off.

Before, the cloud end closed a revoked robot's connection with no word, and its edge end redialled at its
normal pace (0.2 s doubling to 5 s) for as long as the robot stayed revoked. Now the cloud end sends a REFUSE
frame with the reason instead of its HELLO answer; the edge waits longer after each refusal (1 s doubling to
30 s by default), says ``refused: revoked`` in its log and its stats file, and links again at its next dial
once the robot is restored, at once when woken (SIGHUP, which ``fogiac robot restore`` sends the robot's
edge ends on its machine: :func:`fogiac.net.relay.deploy.wake_robot`).

Real ends: a cloud end following the lab fleet's access file, one robot's edge end on its own roscore.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import pytest

from fogiac.net.relay.fleet import ACCESS_FILE, write_access
from fogiac.net.relay.stats import read_stats
from tests.fleet.fleet_support import access, cloud_end, edge_end
from tests.net.relay.relay_support import Master, wait_for

pytestmark = pytest.mark.ros

FIRST, CAP = 0.5, 2.0  # the test's refused_backoff_initial and _max (1 s and 30 s by default)


def _waits(caplog: pytest.LogCaptureFixture) -> list[float]:
    """The waits the edge logged after each refusal, in order."""
    return [float(m.group(1)) for r in caplog.records
            if (m := re.search(r"refused this edge: revoked; retrying in ([0-9.]+) s", r.getMessage()))]


def test_a_revoked_robots_edge_backs_off_says_why_and_links_once_restored(
        masters: tuple[Master, Master], fleet_certs: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    edge_m, cloud_m = masters
    caplog.set_level(logging.WARNING, logger="fogiac.net.relay.edge")
    write_access(fleet_certs / ACCESS_FILE, access(revoked=("arm3",)))
    stats = tmp_path / "relay-edge-planner@arm3.stats.json"
    with cloud_end(cloud_m, fleet_certs) as cloud:
        end = edge_end("arm3", edge_m, fleet_certs, cloud, 9, refused_backoff_initial=FIRST, refused_backoff_max=CAP,
                       stats_file=stats)
        try:
            wait_for(lambda: len(_waits(caplog)) >= 4, 60, "four refusals")
            waits = _waits(caplog)
            # growing from 1 s, capped: not the normal pace (0.1 s doubling to 0.5 s here)
            assert waits[:4] == [FIRST, 2 * FIRST, CAP, CAP], waits
            assert cloud.refused_links == len(waits) and not end.connected.is_set() and end.reconnects == 0
            assert end.link_refused == "revoked"
            wait_for(lambda: stats.exists() and read_stats(stats).link_refused == "revoked", 10, "stats say why")
            assert read_stats(stats).connected is False

            write_access(fleet_certs / ACCESS_FILE, access())  # restored: linked at the next dial, within the cap
            cloud.reload_access()
            wait_for(end.connected.is_set, CAP + 10, "arm3 linked again at its next dial")
            assert end.link_refused is None
            wait_for(lambda: read_stats(stats).connected and read_stats(stats).link_refused is None, 10,
                     "stats say linked")

            caplog.clear()  # revoked while linked: the link is closed, and the redials refused and backed off
            write_access(fleet_certs / ACCESS_FILE, access(revoked=("arm3",)))
            cloud.reload_access()
            wait_for(lambda: len(_waits(caplog)) >= 2, 30, "refused again")
            assert _waits(caplog)[:2] == [FIRST, 2 * FIRST]
        finally:
            end.stop()


def test_a_restored_robots_edge_dials_at_once_when_woken(masters: tuple[Master, Master], fleet_certs: Path,
                                                          caplog: pytest.LogCaptureFixture) -> None:
    """Refused once, its edge waits 600 s; restored and woken (what SIGHUP does), it links in seconds."""
    edge_m, cloud_m = masters
    caplog.set_level(logging.WARNING, logger="fogiac.net.relay.edge")
    write_access(fleet_certs / ACCESS_FILE, access(revoked=("arm2",)))
    with cloud_end(cloud_m, fleet_certs) as cloud:
        end = edge_end("arm2", edge_m, fleet_certs, cloud, 8, refused_backoff_initial=600, refused_backoff_max=600)
        try:
            wait_for(lambda: any("refused this edge: revoked; retrying in 600.0 s" in r.getMessage()
                                 for r in caplog.records), 30, "refused, waiting 600 s")
            write_access(fleet_certs / ACCESS_FILE, access())
            cloud.reload_access()
            end.redial_now()
            wait_for(end.connected.is_set, 20, "arm2 linked once woken")
            assert cloud.refused_links == 1
        finally:
            end.stop()
