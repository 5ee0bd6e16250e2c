"""Zenoh benchmark: a direct Zenoh session vs through fogiac's cloud and edge routers, on loopback.

    .venv/bin/python benchmarks/zenoh/run.py        (or: python -m benchmarks.zenoh)
    ... run.py --only 48KiB,1MiB                     some sizes

The routers are the ones fogiac configures (:mod:`fogiac.net.zenoh.config`, started by the live
tests' :class:`tests.net.zenoh.lab.ZenohLab`): the cloud router listens with mutual TLS and
access control on, the edge router dials it. For 1 KiB, 48 KiB and 1 MiB payloads one publisher
sits on the edge router; the subscriber sits either on the same router (direct: the one hop a
ROS 2 pub/sub pair on the robot takes) or on the cloud router (through: edge router, mutual TLS,
the cloud router's access control). Latency runs publish at a fixed rate, throughput runs as
fast as the publisher can (congestion control "block"); runs alternate between the two and
every figure is reported against direct, measured in this run. Needs eclipse-zenoh.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from benchmarks.relay.run import WARMUP_S, pct, throughput  # noqa: E402  (helpers exist once)
from fogiac.procs import stop_tree  # noqa: E402
from tests.net.zenoh.lab import ZenohLab, free_ports, route  # noqa: E402

NODE = Path(__file__).with_name("node.py")
SIZES = {"1 KiB": 1024, "48 KiB": 48 * 1024, "1 MiB": 1024 * 1024}
LAT_RATE = {"1 KiB": 100.0, "48 KiB": 100.0, "1 MiB": 20.0}
LAT_SECONDS, THR_SECONDS, THR_REPEATS, LAT_REPEATS = 3.0, 3.0, 2, 2
MODES = ("direct", "through")


def key(topic: str) -> str:
    """rmw_zenoh's data key for ``topic`` (domain 0), the shape the cloud router's access control allows."""
    return f"0/{topic.strip('/')}/std_msgs::msg::dds_::ByteMultiArray_/RIHS01_{'0' * 64}"


def topic(mode: str, kind: str, label: str, rep: int) -> str:
    return f"/bench_{mode}_{kind}_{label.replace(' ', '').lower()}_{rep}"


def run_pair(home: Path, pub_port: int, sub_port: int, name: str, size: int, rate: float,
             seconds: float) -> list[tuple[float, float, int, int]]:
    """One publisher and one subscriber; the subscriber's arrivals (time, latency s, bytes, seq)."""
    common = [sys.executable, str(NODE)]
    env = dict(os.environ, PYTHONPATH=str(ROOT), RUST_LOG="error")
    log = open(home / "nodes.log", "a")  # noqa: SIM115 - closed below
    sub = subprocess.Popen([*common, "sub", f"tcp/127.0.0.1:{sub_port}", key(name), "--duration", str(seconds + 0.5)],
                           env=env, stdout=subprocess.PIPE, stderr=log, text=True, start_new_session=True)
    pub = None
    try:
        assert sub.stdout is not None
        if sub.stdout.readline().strip() != "ready":
            raise RuntimeError(f"subscriber failed to start; see {home / 'nodes.log'}")
        pub = subprocess.Popen([*common, "pub", f"tcp/127.0.0.1:{pub_port}", key(name), "--size", str(size),
                                "--rate", str(rate), "--duration", str(seconds)],
                               env=env, stdout=log, stderr=log, start_new_session=True)
        line = sub.stdout.readline()
        pub.wait(timeout=seconds + 60)
        sub.wait(timeout=30)
    finally:
        for proc in (pub, sub):
            if proc is not None and proc.poll() is None:
                stop_tree(proc.pid, grace=5)
        if sub.stdout:
            sub.stdout.close()
        log.close()
    arrivals = json.loads(line)["arrivals"] if line else []
    if not arrivals:
        raise RuntimeError(f"no messages on {name}; see {home / 'nodes.log'}")
    start = arrivals[0][0] + WARMUP_S
    return [a for a in arrivals if a[0] >= start] or arrivals


def main() -> None:
    only = sys.argv[sys.argv.index("--only") + 1].split(",") if "--only" in sys.argv else list(SIZES)
    sizes = {k: v for k, v in SIZES.items() if k.replace(" ", "") in [o.replace(" ", "") for o in only]}
    topics = tuple(topic(mode, kind, label, rep) for label in sizes for mode in MODES for kind in ("thr", "lat")
                   for rep in range(max(THR_REPEATS, LAT_REPEATS)))
    home = Path(tempfile.mkdtemp(prefix="zenoh-bench-"))
    with ZenohLab(home) as lab:
        tls_port, cloud_local, edge_local = free_ports(3)
        lab.router("cloud-router", lab.cloud_config(route(tls_port, to_cloud=topics, to_edge=()),
                                                     local_port=cloud_local))
        lab.router("edge-router", lab.edge_config([("127.0.0.1", tls_port)], local_port=edge_local))
        sub_port = {"direct": edge_local, "through": cloud_local}
        rows = []
        for label, size in sizes.items():
            best = {mode: 0.0 for mode in MODES}
            for rep in range(THR_REPEATS):  # interleaved, best of each: other load on the box hurts both
                for mode in MODES:
                    thr = run_pair(home, edge_local, sub_port[mode], topic(mode, "thr", label, rep), size, 0.0,
                                   THR_SECONDS)
                    best[mode] = max(best[mode], throughput(thr))
            samples: dict[str, list[float]] = {mode: [] for mode in MODES}
            for rep in range(LAT_REPEATS):  # interleaved and pooled, for the same reason
                for mode in MODES:
                    lat = run_pair(home, edge_local, sub_port[mode], topic(mode, "lat", label, rep), size,
                                   LAT_RATE[label], LAT_SECONDS)
                    samples[mode] += [1000 * a[1] for a in lat]
            result = {}
            for mode in MODES:
                ms = samples[mode]
                result[mode] = (statistics.median(ms), pct(ms, 0.99), best[mode], len(ms))
                print(f"  {label:7} {mode:7} median {result[mode][0]:8.3f} ms  p99 {result[mode][1]:8.3f} ms  "
                      f"{result[mode][2] / 1e6:8.1f} MB/s  ({result[mode][3]} msgs)", flush=True)
            d, t = result["direct"], result["through"]
            rows.append((label, t[0] - d[0], t[1] - d[1], t[0] / d[0], t[2] / d[2] if d[2] else 0.0, d, t))
    print("\nsize     added median ms  added p99 ms  latency through/direct  throughput through/direct"
          "  (direct MB/s, through MB/s)")
    for label, add_med, add_p99, lat_ratio, thr_ratio, d, t in rows:
        print(f"{label:8} {add_med:15.3f} {add_p99:13.3f} {lat_ratio:23.2f} {thr_ratio:26.2f}"
              f"  ({d[2] / 1e6:.1f}, {t[2] / 1e6:.1f})")
    print(f"load average at the end {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")


if __name__ == "__main__":
    main()
