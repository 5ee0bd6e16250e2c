"""``status``'s relayed-topics row counts a one-off request after its publisher left (issue 35 item 20).

On the first day (``topics: auto``) the workloads' client publishes one planning request and exits; the
auto topic's route went with the publisher, its counters with it, and ``status`` showed ``-`` in the
relayed-topics row although the request had crossed. A real relay pair between two roscores writes its
edge's stats file as ``up`` has it write; the row ``status`` renders from that file, read the way
``status`` reads it, names the topic, its direction and the message, after the publisher has gone.
"""

from __future__ import annotations

import io
import time
from pathlib import Path

from rich.console import Console

from fogiac.lifecycle.report import relays_table
from fogiac.net.relay import CloudConfig, CloudRelay, EdgeConfig, EdgeRelay, TopicPolicy
from fogiac.net.relay.deploy import edge_links
from tests.net.relay.relay_support import Master, Procs, wait_for


def _rows(folder: Path) -> list[str]:
    out = io.StringIO()
    Console(file=out, width=200, color_system=None).print(relays_table(edge_links(folder, {"planner": "cloud"})))
    return [line.strip().strip("│") for line in out.getvalue().splitlines() if line.startswith("│ planner ")]


def test_a_one_off_request_stays_in_the_status_row(masters: tuple[Master, Master], certs: Path, procs: Procs,
                                                   tmp_path: Path) -> None:
    edge_m, cloud_m = masters
    cloud = CloudRelay(CloudConfig(master_uri=cloud_m.uri, certs=certs, ros_host="127.0.0.1", listen=("127.0.0.1", 0),
                                   poll_interval=0.1, policy=TopicPolicy(auto=True)))
    cloud.start()
    edge = EdgeRelay(EdgeConfig(master_uri=edge_m.uri, certs=certs, ros_host="127.0.0.1", connect=cloud.address,
                                poll_interval=0.1, backoff_max=1.0, policy=TopicPolicy(auto=True),
                                stats_file=tmp_path / "relay-edge-planner.stats.json"))
    edge.start()
    try:
        planner = procs.node(cloud_m, "sub", "/plan_request", "--count", "1000")  # the node, subscribed for good
        client = procs.node(edge_m, "pub", "/plan_request", "--count", "1", "--wait-subs")  # one request, then gone
        wait_for(lambda: len(planner.data()) >= 1, 30, "the request to reach the node")
        wait_for(lambda: client.popen.poll() is not None, 30, "the client to exit")
        wait_for(lambda: "/fogiac_relay_edge" not in edge_m.subscribers("/plan_request"), 10, "the route to go")
        time.sleep(2.5)  # the stats file is written once a second: let it be written after the route went
        (row,) = _rows(tmp_path)
        cells = [cell.strip() for cell in row.split("│")]
        assert cells[0] == "planner" and cells[1].startswith("up"), row
        assert cells[2:5] == ["/plan_request", "in", "1"], row
    finally:
        edge.stop()
        cloud.stop()
