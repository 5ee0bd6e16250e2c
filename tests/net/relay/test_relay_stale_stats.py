"""The watchdog does not trust a stats file whose writer stopped (issue 26 item 9): a real relay pair,
its cloud end SIGSTOPped, its last ``connected: true`` left on disk."""

from __future__ import annotations

import json
import os
import signal
import sys
from pathlib import Path

from fogiac.procs import poll
from fogiac.provision.autostop import IdleClock, read_activity
from tests.net.relay.relay_support import Master, Procs, free_port, wait_for

STALE_S = 3.0  # the watchdog's is 30 s; the judgement is the same, only shorter here


def test_a_stopped_relays_last_connected_true_goes_stale(masters: tuple[Master, Master], certs: Path,
                                                         procs: Procs, tmp_path: Path) -> None:
    edge_m, cloud_m = masters
    port, stats = free_port(), tmp_path / "relay-cloud.stats.json"
    cloud = procs.spawn([sys.executable, "-m", "fogiac", "relay", "cloud", "--listen", f"127.0.0.1:{port}",
                         "--master", cloud_m.uri, "--certs", str(certs), "--ros-host", "127.0.0.1",
                         "--stats-file", str(stats)], cloud_m.env)
    procs.spawn([sys.executable, "-m", "fogiac", "relay", "edge", "--connect", f"127.0.0.1:{port}",
                 "--master", edge_m.uri, "--certs", str(certs), "--ros-host", "127.0.0.1"], edge_m.env)

    def connected() -> bool:
        seen = read_activity(stats, stale_s=STALE_S)
        return seen is not None and seen.connected

    wait_for(connected, 30, "the cloud end to see its edge")
    # control: a running relay rewrites its file every second, so it never looks stale
    assert poll(lambda: None if connected() else False, timeout=STALE_S + 2) is None
    os.killpg(cloud.popen.pid, signal.SIGSTOP)
    try:
        assert poll(lambda: True if not connected() else None, timeout=STALE_S + 10), \
            "a stopped relay's stats kept saying connected"
        assert json.loads(stats.read_text())["connected"] is True  # what the stopped relay left on disk
        clock = IdleClock(idle_s=60, now=0)  # the watchdog's clock on that file: no activity seen
        clock.observe(read_activity(stats, stale_s=STALE_S), now=100)
        assert clock.due(100)
    finally:
        os.killpg(cloud.popen.pid, signal.SIGCONT)
    wait_for(connected, 30, "the resumed cloud end's fresh stats")
