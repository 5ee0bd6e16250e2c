"""Hedged replicas on the ``hosts`` target with the motion planner: robot-side latency, one copy against two.

    flock /tmp/fogiac-netns.lock .venv/bin/python benchmarks/replicas_hosts.py        # every scenario (~10 min)
    flock /tmp/fogiac-netns.lock .venv/bin/python benchmarks/replicas_hosts.py --only 1-healthy,2-killed --count 60

Needs root (network namespaces), sshd, roscore, rospy and OMPL in this interpreter (the lab hosts share the
filesystem, so they run it too). Two namespace lab hosts (tests/provision/sshlab.py) each with its own sshd;
per scenario a stack is provisioned on them the way ``fogiac up`` does (``provision_and_connect``: each
host's roscore, relay cloud end and ``workload: motion_planning`` node under its supervisor; here the edge:
a plain relay edge for one copy, the replica group for two), then torn down. The robot, a rospy node on the
edge master here, sends ``--count`` requests at ``--rate`` Hz (``PoseArray``, ``frame_id`` "easy;seed=i",
stamp base+i: the same search on every replica, so only the impairment differs), timing each path by its
stamp. It first probes until every replica has answered (the planner's workers warm up after start).

One core per host, as separate machines would have: each lab host's sshd (and so everything fogiac starts
there) is pinned with ``taskset``, host h0 to CPU 0, host h1 to CPU 1; the single replica runs on h0
(CPU 0). The edge (relay or replica group), its roscore and the robot run here, unpinned, on the same two
CPUs: a real robot would run them on its own computer.

Impairments, always on h0 (replica 0): ``delayed``: the edge dials it through a user-space TCP proxy
(tests/support/delayproxy.py) holding each chunk ``--delay-ms`` each way (a path is a few hundred bytes:
``tbf`` shapes rate, not latency, and would barely delay it; this kernel has no ``netem``); ``starved``:
its processes in a cgroup v1 ``cpu`` group with ``--quota`` of one CPU; ``killed``: every ``--kill-every``
s one host's processes (all but sshd) are SIGKILLed, alternating h0 and h1, and it is provisioned again
at once (``provision`` alone, as the next ``fogiac up`` would: the edge's group and the other host are
not touched).

Printed per scenario: replies, duplicates delivered (must be 0), lost requests, P50/P95/P99 in ms,
answers won per replica (from the edge group's stats file, the probes' wins subtracted), the kills (host
and seconds into the run), the four slowest requests (index i: sent about i / rate s into the run), and
the load average.

Figures (Debian 12 VM, 2 CPUs, other jobs on the machine at times, 2026-11-26; defaults: 200 requests at
4 Hz, problem ``easy`` (a few ms of planning on a warm node), 50 ms each way on the delayed link, the
starved host held to 5% of a CPU, a host killed at 20 s and at about 42 s; ms; runs 1 and 2 every scenario,
runs 3 and 4 only 1-healthy and 2-killed; won from run 2):

    scenario   dup lost  p50 (run 1 / 2)  p95           p99                        won (run 2)
    1-healthy    0    0  8.0 / 9.4        15.6 / 18.6   20.6 / 20.0 / 21.9 / 16.7  h0 200
    1-delayed    0    0  107.2 / 109.7    112.9 / 119.3 116.7 / 123.8              h0 200
    1-starved    0    0  71.4 / 605.1     186.8 / 1205.8 233.3 / 1302.9            h0 200
    2-delayed    0    0  7.2 / 9.1        15.6 / 16.0   17.6 / 20.7                h0 0, h1 200
    2-killed     0    0  8.3 / 9.9        18.6 / 18.8   23.4 / 25.7 / 17.8 / 15.3  h0 99, h1 101
    2-starved    0    0  7.7 / 7.7        15.4 / 10.7   17.7 / 13.2                h0 11, h1 189
    2-healthy    0    0  7.2 / 7.3        11.6 / 9.5    14.1 / 10.0                h0 103, h1 97

No duplicate delivered and no request lost in any run. P99 with two replicas and one impaired against the
healthy single replica's in the same run: delayed 0.85x / 1.04x, starved 0.86x / 0.66x, killed 1.14x /
1.29x / 0.81x / 0.92x: the 1.2x goal holds in every run but run 2's killed one, whose tail is the request
sent as the first host dies (the slowest in every killed run: 25-34 ms) and the re-provisioning after it,
whose SSH client and fogiac run here on the edge's two CPUs. With 200 requests P99 is the second slowest.
The single starved replica queues (5% of a CPU cannot keep up with 4 Hz on a loaded run 2: P50 605 ms);
two replicas hide it. 2-healthy is faster than 1-healthy: the merge takes each request's quicker copy.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import statistics
import subprocess
import sys
import threading
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.replicas import percentile, report  # noqa: E402
from fogiac.lifecycle.edge import dialed_addresses, edge_dir, provision_and_connect, stop_edge  # noqa: E402
from fogiac.manifest.schema import load_manifest  # noqa: E402
from fogiac.plan.compile import compile_plan  # noqa: E402
from fogiac.plan.model import Plan  # noqa: E402
from fogiac.procs import free_port  # noqa: E402
from fogiac.provision import provision, teardown  # noqa: E402
from fogiac.state import StackState  # noqa: E402
from fogiac.targets.hosts.target import HOSTS  # noqa: E402
from tests.net.relay.relay_support import Master, Proc, Procs, wait_for  # noqa: E402
from tests.provision.sshlab import LabHost, lab_skip_reason, ssh_lab  # noqa: E402
from tests.support.delayproxy import DelayProxy  # noqa: E402
from tests.support.ros import ros_missing  # noqa: E402

REQ, REP = "/motion_planning/request", "/motion_planning/path"
SCENARIOS = ("1-healthy", "1-delayed", "1-starved", "2-delayed", "2-killed", "2-starved", "2-healthy")
CGROUP = Path("/sys/fs/cgroup/cpu")


def robot_main(argv: list[str]) -> None:
    """The robot (run as its own process): probe until ``--go`` exists, then the measured run."""
    parser = argparse.ArgumentParser()
    parser.add_argument("--count", type=int)
    parser.add_argument("--rate", type=float)
    parser.add_argument("--problem", default="easy")
    parser.add_argument("--go", type=Path)
    parser.add_argument("--wait", type=float, default=10.0)
    args = parser.parse_args(argv)
    import rospy
    from geometry_msgs.msg import PoseArray

    base = 100000
    sent: dict[int, float] = {}
    lock = threading.Lock()

    def got(reply: PoseArray) -> None:
        now = time.perf_counter()
        i = reply.header.stamp.secs - base
        with lock:
            t0 = sent.get(i)
        ms = None if t0 is None else round((now - t0) * 1e3, 3)
        print(json.dumps({"i": i, "ms": ms, "poses": len(reply.poses)}), flush=True)

    rospy.init_node("replica_bench_robot", anonymous=True, disable_signals=True)
    pub = rospy.Publisher(REQ, PoseArray, queue_size=100, tcp_nodelay=True)
    sub = rospy.Subscriber(REP, PoseArray, got, queue_size=1000, tcp_nodelay=True)
    while (pub.get_num_connections() == 0 or sub.get_num_connections() == 0) and not rospy.is_shutdown():
        time.sleep(0.05)

    def ask(i: int, seed: int) -> None:
        request = PoseArray()
        request.header.frame_id = f"{args.problem};seed={seed}"
        request.header.stamp = rospy.Time(base + i, 0)
        with lock:
            sent[i] = time.perf_counter()
        pub.publish(request)

    k = 0
    while not args.go.exists():  # probes: negative indices, not counted
        k += 1
        ask(-k, 10**6 + k)
        time.sleep(0.5)
    time.sleep(1.0)
    print("start", flush=True)
    for i in range(args.count):
        ask(i, i)
        time.sleep(1.0 / args.rate)
    time.sleep(args.wait)
    print("done", flush=True)


def pin(host: LabHost, cpu: int) -> None:
    """Every process of the host's namespace (its sshd: what fogiac starts there inherits it) onto ``cpu``."""
    for pid in host.ns.pids():
        subprocess.run(["taskset", "-a", "-p", "-c", str(cpu), str(pid)], capture_output=True)


def kill_host(host: LabHost) -> None:
    for pid in host.ns.pids():
        with contextlib.suppress(OSError):
            if Path(f"/proc/{pid}/comm").read_text().strip() != "sshd":
                os.kill(pid, signal.SIGKILL)


@contextlib.contextmanager
def starved(host: LabHost, quota: float) -> Iterator[None]:
    """The host's processes but sshd in a cgroup v1 cpu group allowed ``quota`` of one CPU."""
    group = CGROUP / f"fogiac-bench-{os.getpid()}"
    group.mkdir()
    try:
        (group / "cpu.cfs_period_us").write_text("100000")
        (group / "cpu.cfs_quota_us").write_text(str(int(100000 * quota)))
        for pid in host.ns.pids():
            with contextlib.suppress(OSError):
                if Path(f"/proc/{pid}/comm").read_text().strip() != "sshd":
                    (group / "cgroup.procs").write_text(str(pid))
        yield
    finally:
        for line in (group / "cgroup.procs").read_text().split():
            with contextlib.suppress(OSError):
                (CGROUP / "cgroup.procs").write_text(line)
        with contextlib.suppress(OSError):
            group.rmdir()


def manifest(path: Path, stack: str, hosts: list[LabHost], key: Path, edge: Master, replicas: int) -> Plan:
    used = hosts[:replicas]
    lines = [f"name: {stack}", "cloud:", "  provider: hosts", "  hosts:"]
    lines += [f"    - {{name: {h.name}, address: {h.address}, user: root, key: {key}}}" for h in used]
    lines += [f'edge: {{ros_master: "{edge.uri.rstrip("/")}"}}', "nodes:", "  - name: planner",
              "    machine: t3.small", "    workload: motion_planning",
              f"    topics: {{in: [{REQ}], out: [{REP}]}}", f"    message_types: {{{REP}: geometry_msgs/PoseArray}}"]
    if replicas > 1:
        lines += [f"    replicas: {replicas}", f"    replica_hosts: [{', '.join(h.name for h in used)}]"]
    else:
        lines += [f"    host: {used[0].name}"]
    path.write_text("\n".join(lines) + "\n")
    return compile_plan(load_manifest(path))




def group_stats(plan: Plan) -> dict:
    try:
        return json.loads((edge_dir(plan) / "relay-replicas-planner.stats.json").read_text())
    except (OSError, ValueError):
        return {}


def run(scenario: str, args: argparse.Namespace, home: Path, hosts: list[LabHost], key: Path, edge: Master,
        procs: Procs) -> dict:
    two = scenario.startswith("2")
    stack = f"mpbench{scenario.replace('-', '')}"
    folder = home / scenario
    folder.mkdir()
    plan = manifest(folder / "fogiac.yaml", stack, hosts, key, edge, 2 if two else 1)
    by_name = {h.name: h for h in hosts}
    access = {n: replace(a, base_dir=str(by_name[n].base_dir / stack), ship_code=False)
              for n, a in HOSTS.access(plan, state_dir=folder, python=sys.executable).items()}
    connect = {n: f"{a.address}:{plan.host(n).relay_port}" for n, a in access.items()}
    impaired = hosts[0]
    proxy = None
    if scenario.endswith("delayed"):
        proxy = DelayProxy((impaired.address, plan.host(impaired.name).relay_port), args.delay_ms / 1e3)
        connect[impaired.name] = f"127.0.0.1:{proxy.port}"
    stop = threading.Event()
    kills: list[str] = []
    probes: dict[str, int] = {}
    robot: Proc | None = None
    state = StackState(plan.stack)
    try:
        provision_and_connect(plan, access=access, connect=connect, master=plan.edge_master)
        with starved(impaired, args.quota) if scenario.endswith("starved") else contextlib.nullcontext():
            go = folder / "go"
            robot = procs.spawn([sys.executable, __file__, "robot", "--count", str(args.count), "--rate",
                                 str(args.rate), "--go", str(go), "--problem", args.problem], edge.env)

            def warm() -> bool:
                if two:
                    return all(r.get("answers", 0) > 0 for r in group_stats(plan).get("replicas", [{}]))
                return any(line.startswith("{") for line in robot.lines)

            wait_for(warm, 180, "every replica's first answer")
            go.touch()
            wait_for(lambda: "start" in robot.lines, 30, "the robot's start")
            started = time.monotonic()  # request i is sent about i / rate s after this
            probes = {r["host"]: r["won"] for r in group_stats(plan).get("replicas", [])}  # won before the run
            chaos = None
            if scenario.endswith("killed"):
                def killer() -> None:
                    k = 0
                    while not stop.wait(args.kill_every):
                        victim = hosts[k % 2]
                        kill_host(victim)
                        kills.append(f"{victim.name}@{time.monotonic() - started:.1f}s")
                        # the next `fogiac up`: every host checked, the dead one's services started again
                        provision(plan, hosts=access, state_dir=state.ensure(), certs_dir=state.certs,
                                  dialed=dialed_addresses(connect))
                        k += 1
                chaos = threading.Thread(target=killer, daemon=True)
                chaos.start()
            wait_for(lambda: "done" in robot.lines, args.count / args.rate + 300, "the robot's run")
            stop.set()
            if chaos is not None:
                chaos.join()
        time.sleep(1.5)  # the group's stats file is rewritten every second
        won = {r["host"]: r["won"] - probes.get(r["host"], 0) for r in group_stats(plan).get("replicas", [])} \
            if two else {hosts[0].name: None}
        replies = [json.loads(line) for line in robot.lines if line.startswith("{")]
        measured = [r for r in replies if r["i"] >= 0]
        seen = Counter(r["i"] for r in measured)
        ms = [r["ms"] for r in measured if r["ms"] is not None]
        return {
            "scenario": scenario, "requests": args.count, "replies": len(measured),
            "duplicates": sum(n - 1 for n in seen.values() if n > 1), "lost": args.count - len(seen),
            "unsolved": sum(1 for r in measured if not r["poses"]),
            "p50": round(statistics.median(ms), 1), "p95": round(percentile(ms, 0.95), 1),
            "p99": round(percentile(ms, 0.99), 1), "won": won, "kills": kills,
            "slowest": sorted(([r["i"], r["ms"]] for r in measured if r["ms"] is not None), key=lambda x: -x[1])[:4],
            "load": os.getloadavg()[0],
        }
    finally:
        stop.set()
        if robot is not None:
            procs.kill(robot)
        stop_edge(plan)
        with contextlib.suppress(Exception):
            teardown(plan, hosts=access, state_dir=state.ensure())
        for host in hosts[:2 if two else 1]:
            kill_host(host)  # anything teardown left (a host killed mid-provision)
        if proxy is not None:
            proxy.close()


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "robot":
        robot_main(sys.argv[2:])
        return
    parser = argparse.ArgumentParser()
    parser.add_argument("--only", default=",".join(SCENARIOS))
    parser.add_argument("--count", type=int, default=200)
    parser.add_argument("--rate", type=float, default=4.0)
    parser.add_argument("--problem", default="easy", help="a shipped motion-planning problem")
    parser.add_argument("--delay-ms", type=float, default=50.0, help="each way, through the impaired link")
    parser.add_argument("--quota", type=float, default=0.05, help="the starved host's share of one CPU")
    parser.add_argument("--kill-every", type=float, default=20.0)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    why = ros_missing() or lab_skip_reason()
    if why:
        sys.exit(f"skipped: {why}")
    home = Path(os.environ.get("TMPDIR", "/tmp")) / f"fogiac-bench-replicas-hosts-{os.getpid()}"
    home.mkdir(parents=True)
    os.environ["FOGIAC_STATE_DIR"] = str(home / "state")
    procs = Procs(home)
    results = []
    print(f"two lab hosts, one CPU each (h0: CPU 0, h1: CPU 1; one replica: h0); edge and robot unpinned; "
          f"{args.count} requests at {args.rate} Hz, problem {args.problem}", flush=True)
    try:
        with ssh_lab(home / "lab", 2) as (hosts, key):
            for cpu, host in enumerate(hosts):
                pin(host, cpu)
            edge = procs.roscore(free_port())
            for scenario in args.only.split(","):
                result = run(scenario, args, home, hosts, key, edge, procs)
                results.append(result)
                print(json.dumps(result), flush=True)
    finally:
        procs.close()  # each process group signalled, then SIGKILLed (stop_group): no rosmaster outlives it
    report(results, args.json)


if __name__ == "__main__":
    main()
