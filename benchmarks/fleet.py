"""A fleet through one relay cloud end: per-robot latency, loss, throughput and the cloud end's memory per robot.

    .venv/bin/python benchmarks/fleet.py                      # 1, 8 and 32 robots at 10 Hz (~4 min), needs rospy
    .venv/bin/python benchmarks/fleet.py --robots 1,8 --count 200 --work-ms 0

On ``local`` (loopback): each robot is its own ROS master (``rosmaster --core``), its own relay edge end
(``fogiac relay edge`` with the robot's own client certificate, as ``up`` issues them) and a rospy robot
sending ``--rate`` requests a second (``std_msgs/Header``) on the shared request topic; the cloud side is
one master, one ``fogiac relay cloud`` following the fleet's access file (``fleet.json``: every robot, the
shared request/reply topics) and one shared echo node (``--work-ms`` of busy CPU per request). Each robot
stamps its requests from its own base (robot k: 1000 + 100000 k seconds), so a reply that reaches a robot
that did not ask for it is counted as *foreign* (a reply routed to the wrong robot); with per-robot reply
routing it must be 0.

Printed per fleet size: requests, own replies, foreign replies, lost requests, P50/P99 in ms over every
robot's replies and the worst robot's P99, total replies a second (each robot's own replies over
the span from its first to its last, summed), the cloud end's resident memory per
added robot (its RSS with every robot linked and replying, minus its RSS before the first robot dialled,
over the number of robots), and the load average. The machine may be shared: read figures with the load.

Goals on 2 cores (issue 34): 32 robots at 10 Hz, no loss, P99 <= 50 ms; <= 5 MB of cloud-end memory per robot.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
import xmlrpc.client
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fogiac.certs import edge_identity, edge_role, load_or_create_edges, write_relay_lab  # noqa: E402
from fogiac.net.relay.fleet import ACCESS_FILE, FleetAccess, Robot, SharedPair, write_access  # noqa: E402
from tests.net.relay.relay_support import Master, Proc, Procs, free_port, wait_for  # noqa: E402
from tests.support.ros import ros_missing  # noqa: E402

NODES = ROOT / "tests" / "net" / "relay" / "replica_nodes.py"
REQ, REP = "/fleet_bench/request", "/fleet_bench/reply"
STACK = "fleetbench"
BASE, STRIDE = 1000, 100000  # robot k stamps request i with BASE + k * STRIDE + i seconds


def fleet_certs(folder: Path, robots: list[str]) -> None:
    """A lab CA and cloud-end pair, each robot's own client pair, and the access file naming them all."""
    lab = folder.with_name(folder.name + "-lab")
    write_relay_lab(STACK, lab)
    shutil.copytree(lab, folder)
    load_or_create_edges(STACK, folder, robots)
    for name in ("server.pem", "server.key"):  # the lab's cloud-end pair (a stack's host makes its own)
        shutil.copy(lab / name, folder / name)
    shared = frozenset((REQ, REP))
    pair = SharedPair("echo", frozenset((REQ,)), frozenset((REP,)))  # replies routed to the robot that asked
    write_access(folder / ACCESS_FILE, FleetAccess(
        {edge_identity(STACK, r): Robot(r, edge_identity(STACK, r), shared) for r in robots}, frozenset(), (pair,)))


def master(procs: Procs) -> Master:
    """A bare ROS master (no rosout): a robot's, cheap enough to run 32 of on two cores."""
    port = free_port()
    uri = f"http://127.0.0.1:{port}/"
    env = dict(os.environ, ROS_HOSTNAME="127.0.0.1", ROS_MASTER_URI=uri, ROS_HOME=str(procs.home),
               ROS_LOG_DIR=str(procs.home / "log"), PYTHONUNBUFFERED="1", PYTHONPATH=str(ROOT))
    proc = procs.spawn(["rosmaster", "--core", "-p", str(port)], env)

    def up() -> bool:
        try:
            xmlrpc.client.ServerProxy(uri).getSystemState("/bench")
            return True
        except OSError:
            return False

    wait_for(up, 60, f"rosmaster on port {port}")
    return Master(uri, env, proc)


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError(f"no VmRSS for pid {pid}")


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


def run(n: int, args: argparse.Namespace, home: Path) -> dict:
    robots = [f"r{k}" for k in range(n)]
    certs = home / f"certs-{n}"
    fleet_certs(certs, robots)
    procs = Procs(home)
    try:
        cloud_m = master(procs)
        port = free_port()
        cloud = procs.spawn([sys.executable, "-m", "fogiac", "relay", "cloud", "--listen", f"127.0.0.1:{port}",
                             "--master", cloud_m.uri, "--certs", str(certs), "--ros-host", "127.0.0.1",
                             "--out", REQ, "--in", REP, "--topics", "", "--queue-depth", "100"], cloud_m.env)
        echo = procs.spawn([sys.executable, str(NODES), "echo", REQ, REP, "--name", "cloud",
                            "--work-ms", str(args.work_ms)], cloud_m.env)
        wait_for(lambda: "ready" in echo.lines, 60, "the echo node")
        time.sleep(2.0)  # the cloud end settles (its first graph poll) before its memory is read
        rss0 = rss_mb(cloud.popen.pid)
        clients: list[Proc] = []
        for k, robot in enumerate(robots):
            edge_m = master(procs)
            procs.spawn([sys.executable, "-m", "fogiac", "relay", "edge", "--connect", f"127.0.0.1:{port}",
                         "--master", edge_m.uri, "--certs", str(certs), "--client", edge_role(STACK, robot),
                         "--ros-host", "127.0.0.1", "--out", REQ, "--in", REP, "--topics", "",
                         "--queue-depth", "100"], edge_m.env)
            clients.append(procs.spawn([sys.executable, str(NODES), "robot", REQ, REP, "--count", str(args.count),
                                        "--rate", str(args.rate), "--base", str(BASE + k * STRIDE),
                                        "--wait", "5"], edge_m.env))
        wait_for(lambda: all(any(line.startswith("{") for line in c.lines) for c in clients),
                 120 + 2 * n, "every robot's first reply")
        rss = rss_mb(cloud.popen.pid)  # every robot linked and replying
        wait_for(lambda: all("done" in c.lines for c in clients), args.count / args.rate + 120 + 2 * n,
                 "every robot's run")
        load = os.getloadavg()[0]
        ms: list[float] = []
        worst_p99 = 0.0
        own = foreign = lost = 0
        rate = 0.0  # replies a second, summed over the robots (each over its own first-to-last reply)
        for c in clients:
            replies = [json.loads(line) for line in c.lines if line.startswith("{")]
            mine = [r for r in replies if 0 <= r["i"] < args.count]
            foreign += len(replies) - len(mine)
            own += len(mine)
            lost += args.count - len({r["i"] for r in mine})
            times = [r["ms"] for r in mine if r["ms"] is not None]
            ms += times
            arrivals = [r["t"] for r in mine]
            if len(arrivals) > 1:
                rate += len(arrivals) / (max(arrivals) - min(arrivals))
            if times:
                worst_p99 = max(worst_p99, percentile(times, 0.99))
        return {"robots": n, "requests": n * args.count, "own": own, "foreign": foreign, "lost": lost,
                "p50": round(statistics.median(ms), 1) if ms else None,
                "p99": round(percentile(ms, 0.99), 1) if ms else None, "worst_p99": round(worst_p99, 1),
                "replies_per_s": round(rate, 1), "cloud_mb_per_robot": round((rss - rss0) / n, 2),
                "cloud_rss_mb": round(rss, 1), "load": round(load, 1)}
    finally:
        procs.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="1,8,32", help="fleet sizes, comma-separated")
    parser.add_argument("--count", type=int, default=300, help="requests per robot")
    parser.add_argument("--rate", type=float, default=10.0, help="requests a second per robot")
    parser.add_argument("--work-ms", type=float, default=0.0, help="the shared node's busy CPU per request")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    why = ros_missing()
    if why:
        sys.exit(f"skipped: {why}")
    home = Path(os.environ.get("TMPDIR", "/tmp")) / f"fogiac-bench-fleet-{os.getpid()}"
    home.mkdir(parents=True)
    results = []
    try:
        for n in (int(x) for x in args.robots.split(",")):
            result = run(n, args, home)
            results.append(result)
            print(json.dumps(result), flush=True)
    finally:
        subprocess.run(["rm", "-rf", str(home)], check=False)
    print(f"\n{'robots':>6} {'requests':>8} {'own':>6} {'foreign':>7} {'lost':>5} {'p50':>6} {'p99':>6} "
          f"{'worst p99':>9} {'replies/s':>9} {'MB/robot':>8} {'load':>5}")
    for r in results:
        print(f"{r['robots']:>6} {r['requests']:>8} {r['own']:>6} {r['foreign']:>7} {r['lost']:>5} {r['p50']!s:>6} "
              f"{r['p99']!s:>6} {r['worst_p99']:>9} {r['replies_per_s']:>9} {r['cloud_mb_per_robot']:>8} "
              f"{r['load']:>5}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
