"""Hedged replicas through the relay: robot-side latency with one copy of a node, and with two.

    .venv/bin/python benchmarks/replicas.py              # every scenario (~4 min), needs roscore + rospy
    .venv/bin/python benchmarks/replicas.py --only 2-delayed,2-killed --rate 10 --work-ms 20

On ``local`` (loopback, not the ``hosts`` target with the motion planner): a roscore for the robot and
one per replica; on each replica's master a rospy "echo with work" node (``std_msgs/Header`` in, the same
stamp out after ``--work-ms`` of busy CPU) and a ``fogiac relay cloud`` process; on the robot's master a
rospy robot sending ``--rate`` requests a second and timing each reply. One replica runs through a
plain ``fogiac relay edge``; two through ``python -m fogiac.net.relay.replicas`` (hedge ``all``).

Impairments: ``delayed`` puts a user-space TCP proxy holding every chunk ``--delay-ms`` in each
direction between the edge and that replica's cloud end; ``killed`` SIGKILLs one replica's cloud end
every 20 s (alternating) and restarts it 5 s later; ``starved`` stops that replica's echo node for
150 ms of every 200 ms (SIGSTOP/SIGCONT duty cycle: a CPU share of 25%).

Printed per scenario: replies, duplicates delivered (must be 0), lost requests, P50/P95/P99 in ms,
which replica won how often, and the load average. The machine may be shared: read figures with it.

Figures (Debian 12 VM, 2 CPUs shared with other jobs, 2026-11-26; defaults: 300 requests at 10 Hz,
20 ms work, 50 ms each way on the delayed link; two runs, the second after the group moved onto the
shared first-reply core; ms, load average at the end of each scenario):

    scenario    dup lost  p50 (run 1 / 2)  p95            p99            won (run 2)     load
    1-healthy     0    0  23.2 / 28.3      28.5 / 40.8    30.9 / 52.1    r0 300          4.1 / 7.5
    1-delayed     0    0  128.7 / 127.6    156.2 / 138.8  219.2 / 145.6  r0 300          6.8 / 7.9
    1-starved     0    0  157.7 / 107.2    240.1 / 177.8  259.7 / 205.0  r0 300          7.2 / 5.6
    2-delayed     0    0  25.6 / 26.6      37.1 / 37.3    42.6 / 41.7    r1 300          6.6 / 6.9
    2-killed      0    0  27.3 / 26.4      37.9 / 38.8    43.0 / 49.3    r0 301, r1 299  8.3 / 8.7
    2-starved     0    0  27.2 / 27.1      40.4 / 38.6    47.3 / 45.8    r0 13, r1 287   8.1 / 9.1
    2-healthy     0    0  25.3 / 24.6      33.0 / 31.8    35.2 / 37.7    r0 137, r1 163  7.7 / 7.5

No duplicate and no lost request in any scenario (2-killed: 600 requests over 60 s, a cloud end killed
at 20 s and 40 s). With one replica impaired, two replicas keep P50 within 1-4 ms of the healthy single
replica and P99 at 41.7-49.3 ms against 30.9-52.1 ms: the 1.2x goal on P99 is met against run 2's
healthy figure, not against run 1's. On this box both replicas, both relay ends and the robot share two
CPUs at load 5-9, so a second replica's 20 ms of busy work per request competes with the first's (the
2-healthy row costs about as much as the impaired ones); on separate hosts it would not. The hosts target
with the motion planner, each replica on a core of its own: benchmarks/replicas_hosts.py.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import sys
import threading
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fogiac.net.relay.tls import write_relay_lab  # noqa: E402
from tests.net.relay.relay_support import Master, Proc, Procs, free_port, wait_for  # noqa: E402
from tests.support.delayproxy import DelayProxy  # noqa: E402
from tests.support.ros import ros_missing  # noqa: E402

NODES = ROOT / "tests" / "net" / "relay" / "replica_nodes.py"
REQ, REP = "/bench/request", "/bench/reply"
SCENARIOS = ("1-healthy", "1-delayed", "1-starved", "2-delayed", "2-killed", "2-starved", "2-healthy")


class Replica:
    def __init__(self, procs: Procs, certs: Path, name: str, work_ms: float) -> None:
        self.procs, self.certs, self.name = procs, certs, name
        self.master = procs.roscore()
        self.port = free_port()
        self.echo = self._node("echo", REQ, REP, "--name", name, "--work-ms", str(work_ms))
        self.cloud = self.start_cloud()

    def _node(self, *args: str) -> Proc:
        proc = self.procs.spawn([sys.executable, str(NODES), *args], self.master.env)
        wait_for(lambda: "ready" in proc.lines, 30, f"{args[0]} node")
        return proc

    def start_cloud(self) -> Proc:
        return self.procs.spawn([sys.executable, "-m", "fogiac", "relay", "cloud", "--listen",
                                 f"127.0.0.1:{self.port}", "--master", self.master.uri, "--certs", str(self.certs),
                                 "--ros-host", "127.0.0.1", "--out", REQ, "--in", REP, "--topics", ""],
                                dict(self.master.env, PYTHONPATH=str(ROOT)))

    def kill_cloud(self) -> None:
        self.procs.kill(self.cloud, signal.SIGKILL)


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


def report(results: list[dict], json_path: Path | None) -> None:
    """The table of every scenario's replies, duplicates, losses, percentiles and wins (and the JSON, if asked)."""
    print(f"\n{'scenario':<11} {'replies':>7} {'dup':>4} {'lost':>4} {'p50':>7} {'p95':>7} {'p99':>7}  won  load")
    for r in results:
        print(f"{r['scenario']:<11} {r['replies']:>7} {r['duplicates']:>4} {r['lost']:>4} {r['p50']:>7} "
              f"{r['p95']:>7} {r['p99']:>7}  {r['won']}  {r['load']:.1f}")
    if json_path:
        json_path.write_text(json.dumps(results, indent=1))


def run(scenario: str, args: argparse.Namespace, procs: Procs, certs: Path, edge: Master) -> dict:
    count = args.count if scenario != "2-killed" else max(args.count, int(args.rate * 60))
    two = scenario.startswith("2")
    replicas = [Replica(procs, certs, f"r{i}", args.work_ms) for i in range(2 if two else 1)]
    impaired = replicas[0]
    proxy = DelayProxy(("127.0.0.1", impaired.port), args.delay_ms / 1e3) if scenario.endswith("delayed") else None
    addresses = [f"127.0.0.1:{proxy.port if proxy and r is impaired else r.port}" for r in replicas]
    env = dict(edge.env, PYTHONPATH=str(ROOT))
    common = ["--master", edge.uri, "--certs", str(certs), "--ros-host", "127.0.0.1", "--out", REQ, "--in", REP,
              "--topics", "", "--queue-depth", "100"]
    if two:
        argv = [sys.executable, "-m", "fogiac.net.relay.replicas", "--group", "bench", *common,
                "--name", f"/bench_{scenario.replace('-', '_')}"]
        argv += [a for i, address in enumerate(addresses) for a in ("--replica", f"{i},r{i},{address}")]
    else:
        argv = [sys.executable, "-m", "fogiac", "relay", "edge", "--connect", addresses[0], *common,
                "--name", f"/bench_{scenario.replace('-', '_')}"]
    edge_end = procs.spawn(argv, env)
    stop = threading.Event()
    chaos: threading.Thread | None = None
    if scenario.endswith("killed"):
        def killer() -> None:
            k = 0
            while not stop.wait(20.0):
                victim = replicas[k % 2]
                victim.kill_cloud()
                if stop.wait(5.0):
                    return
                victim.cloud = victim.start_cloud()
                k += 1
        chaos = threading.Thread(target=killer, daemon=True)
    elif scenario.endswith("starved"):
        def starve() -> None:
            pid = impaired.echo.popen.pid
            while not stop.is_set():
                os.kill(pid, signal.SIGSTOP)
                time.sleep(0.15)
                os.kill(pid, signal.SIGCONT)
                time.sleep(0.05)
        chaos = threading.Thread(target=starve, daemon=True)
    robot = procs.spawn([sys.executable, str(NODES), "robot", REQ, REP, "--count", str(count), "--rate",
                         str(args.rate), "--wait", "5"], edge.env)
    # the robot starts sending once the edge links it to a replica: chaos starts with its first reply
    wait_for(lambda: any(line.startswith("{") for line in robot.lines), 120, "the first reply")
    if chaos is not None:
        chaos.start()
    wait_for(lambda: "done" in robot.lines, count / args.rate + 120, "the robot's run")
    stop.set()
    if chaos is not None:
        chaos.join()
    if scenario.endswith("starved"):
        os.kill(impaired.echo.popen.pid, signal.SIGCONT)
    replies = [json.loads(line) for line in robot.lines if line.startswith("{")]
    seen = Counter(r["i"] for r in replies)
    ms = [r["ms"] for r in replies if r["ms"] is not None]
    result = {
        "scenario": scenario, "requests": count, "replies": len(replies),
        "duplicates": sum(n - 1 for n in seen.values() if n > 1), "lost": count - len(seen),
        "p50": round(statistics.median(ms), 1), "p95": round(percentile(ms, 0.95), 1),
        "p99": round(percentile(ms, 0.99), 1), "won": dict(Counter(r["from"] for r in replies)),
        "load": os.getloadavg()[0],
    }
    for proc in [robot, edge_end] + [p for r in replicas for p in (r.cloud, r.echo)]:
        procs.kill(proc)
    for r in replicas:
        if r.master.proc is not None:
            procs.kill(r.master.proc)
    if proxy is not None:
        proxy.close()
    return result


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--only", default=",".join(SCENARIOS))
    parser.add_argument("--count", type=int, default=300)
    parser.add_argument("--rate", type=float, default=10.0)
    parser.add_argument("--work-ms", type=float, default=20.0)
    parser.add_argument("--delay-ms", type=float, default=50.0, help="each way, through the impaired link")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    why = ros_missing()
    if why:
        sys.exit(f"skipped: {why}")
    home = Path(os.environ.get("TMPDIR", "/tmp")) / f"fogiac-bench-replicas-{os.getpid()}"
    home.mkdir(parents=True)
    certs = home / "certs"
    write_relay_lab("bench", certs)
    procs = Procs(home)
    results = []
    try:
        edge = procs.roscore()
        for scenario in args.only.split(","):
            result = run(scenario, args, procs, certs, edge)
            results.append(result)
            print(json.dumps(result), flush=True)
    finally:
        procs.close()
    report(results, args.json)


if __name__ == "__main__":
    main()
