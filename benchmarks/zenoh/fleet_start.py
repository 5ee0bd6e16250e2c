"""How long a Zenoh fleet's cloud router takes to carry its robots: at start, and for one robot added.

    .venv/bin/python benchmarks/zenoh/fleet_start.py                  # 8 and 32 robots, twice each (~1 min)
    .venv/bin/python benchmarks/zenoh/fleet_start.py --robots 1,8 --repeat 1

A fleet's cloud router (``python -m fogiac.net.zenoh.router --fleet-file``, :mod:`fogiac.net.zenoh.gate`) opens
one Zenoh router (a *front*) per admitted robot behind its TLS gate; a robot is admitted, and its edge's links
carried, once its front is open. One run writes a fleet file of ``N`` robots (certificate names and router ids
as ``up`` writes them; no robot dials), starts the router process on the config ``up`` renders (the host's
certificate made as on a host, through the live tests' :class:`tests.net.zenoh.lab.ZenohLab`) and times, from
the process's start: ``ready`` (the core and the gate up), and every robot admitted (the process's
``robot NAME: admitted`` lines). Then it adds one robot to the file and times that robot admitted (the process
reads the file every second, so up to a second of that is the poll) and checks that no other robot was touched.
Needs eclipse-zenoh.
"""

from __future__ import annotations

import argparse
import os
import queue
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from fogiac.net.zenoh import deploy, tls  # noqa: E402
from fogiac.net.zenoh.config import cloud_router  # noqa: E402
from fogiac.procs import stop_tree  # noqa: E402
from fogiac.state import write_json_atomic  # noqa: E402
from tests.net.zenoh.lab import STACK, ZenohLab, free_ports, route  # noqa: E402

TIMEOUT_S = 120.0


def fleet_doc(robots: list[str]) -> dict[str, object]:
    return {"robots": {r: {"common_name": tls.edge_name(STACK, r), "zid": deploy.edge_router_id(STACK, r)}
                       for r in robots}, "revoked": []}


def lines_of(stream: object, into: queue.Queue[tuple[float, str]]) -> None:
    for line in stream:  # type: ignore[attr-defined]
        into.put((time.monotonic(), line.strip()))


def admitted(lines: queue.Queue[tuple[float, str]], robots: set[str], seen: list[str]) -> float:
    """When the last of ``robots`` was admitted; every other line the process wrote meanwhile goes to ``seen``."""
    left, deadline = set(robots), time.monotonic() + TIMEOUT_S
    when = 0.0
    while left:
        try:
            when, line = lines.get(timeout=max(0.0, deadline - time.monotonic()))
        except queue.Empty:
            raise RuntimeError(f"not admitted within {TIMEOUT_S:.0f} s: {sorted(left)}; it wrote {seen}") from None
        robot = line.removeprefix("robot ").removesuffix(": admitted")
        if robot in left and line.endswith(": admitted"):
            left.discard(robot)
        else:
            seen.append(line)
    return when


def one_run(home: Path, n: int) -> tuple[float, float, float, list[str]]:
    """Seconds from the process's start to ``ready`` and to all ``n`` robots admitted; to one more admitted."""
    lab = ZenohLab(home)
    tls_port, local_port = free_ports(2)
    robots = [f"r{k}" for k in range(1, n + 1)]
    fleet = home / "zenoh-fleet.json"
    write_json_atomic(fleet, fleet_doc(robots))
    config = cloud_router(route(tls_port), listen_host="127.0.0.1", tls=lab.host_files("gpu"),
                          local_port=local_port, robots={})
    config["id"] = deploy.router_id(STACK, "gpu")
    path = home / "cloud-router.json"
    write_json_atomic(path, config)
    env = dict(os.environ, PYTHONPATH=str(ROOT), RUST_LOG="error")
    start = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-m", "fogiac.net.zenoh.router", str(path), "--fleet-file", str(fleet)],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        assert proc.stdout is not None and proc.stderr is not None
        if proc.stdout.readline().strip() != "ready":
            raise RuntimeError(f"the router did not start: {proc.stderr.read()[-2000:]}")
        ready = time.monotonic() - start
        lines: queue.Queue[tuple[float, str]] = queue.Queue()
        threading.Thread(target=lines_of, args=(proc.stderr, lines), daemon=True).start()
        other: list[str] = []
        everyone = admitted(lines, set(robots), other) - start
        added = f"r{n + 1}"
        write_json_atomic(fleet, fleet_doc([*robots, added]))
        written = time.monotonic()
        one = admitted(lines, {added}, other) - written
        return ready, everyone, one, other
    finally:
        stop_tree(proc.pid, grace=10)


def main() -> None:
    parser = argparse.ArgumentParser(prog="benchmarks/zenoh/fleet_start.py")
    parser.add_argument("--robots", default="8,32", help="fleet sizes, comma separated")
    parser.add_argument("--repeat", type=int, default=2, help="runs per size (each row is one)")
    args = parser.parse_args()
    print(f"{'robots':>6} {'ready s':>8} {'all admitted s':>15} {'one added s':>12} {'load':>5}")
    for n in (int(x) for x in args.robots.split(",")):
        for _ in range(args.repeat):
            with tempfile.TemporaryDirectory(prefix="fogiac-fleet-start-") as home:
                ready, everyone, one, other = one_run(Path(home), n)
            load = os.getloadavg()[0]
            print(f"{n:>6} {ready:>8.2f} {everyone:>15.2f} {one:>12.2f} {load:>5.1f}", flush=True)
            if other:
                print(f"       (it also wrote: {other})", flush=True)


if __name__ == "__main__":
    main()
