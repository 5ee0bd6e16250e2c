"""Routers as fogiac configures them, and ROS 2 node stand-ins, as real processes on loopback.

A :class:`ZenohLab` writes fogiac's rendered configs and certificates under ``tmp_path``, runs
each router with ``python -m fogiac.net.zenoh.router`` and each "ROS 2 node" with
``python -m tests.net.zenoh.ros2node``; every process it started is stopped on exit. The cloud
router's key is made as on a real host: in a :class:`LocalHost` folder, by the same code that
makes every host's key (:mod:`fogiac.net.hostcert`), only its CSR signed by the lab's CA.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fogiac.certs import KeyPair, new_ca
from fogiac.net import hostcert
from fogiac.net.zenoh import tls
from fogiac.net.zenoh.config import TlsFiles, cloud_router, edge_router
from fogiac.net.zenoh.deploy import router_folder
from fogiac.plan.model import RelayRoute
from fogiac.procs import free_port, poll, stop_tree
from fogiac.provision.local import LocalHost

REPO = Path(__file__).resolve().parents[3]
STACK = "ros2-test"
IN_TOPICS = ("/chatter_in", "/camera/image")  # robot -> cloud
OUT_TOPICS = ("/result", "/overlay")  # cloud -> robot


def route(port: int, *, to_cloud: tuple[str, ...] = IN_TOPICS, to_edge: tuple[str, ...] = OUT_TOPICS) -> RelayRoute:
    return RelayRoute(host="gpu", connect_via="loopback", port=port, auto=False, to_cloud=to_cloud, to_edge=to_edge,
                      listed=(), compression=(), queue_size=2)


def read_events(path: Path) -> list[dict[str, Any]]:
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.endswith("}")]


@dataclass
class ZenohLab:
    root: Path
    ca: KeyPair = field(default_factory=lambda: new_ca(f"fogiac CA {STACK}"))
    procs: list[subprocess.Popen] = field(default_factory=list)

    def __enter__(self) -> ZenohLab:
        return self

    def __exit__(self, *exc: object) -> None:
        for proc in reversed(self.procs):
            self.stop(proc)

    def stop(self, proc: subprocess.Popen, *, kill: bool = False) -> None:
        if proc.poll() is None:
            if kill:
                proc.kill()
                proc.wait(10)
            else:
                stop_tree(proc.pid, grace=5)
        for stream in (proc.stdout, proc.stderr):
            if stream:
                stream.close()

    def _start(self, args: list[str], name: str) -> subprocess.Popen:
        env = dict(os.environ, PYTHONPATH=str(REPO), RUST_LOG="error")
        proc = subprocess.Popen([sys.executable, *args], cwd=REPO, env=env, stdout=subprocess.PIPE,
                                stderr=open(self.root / f"{name}.log", "ab"), text=True)
        self.procs.append(proc)
        line = proc.stdout.readline() if proc.stdout else ""
        if line.strip() != "ready":
            proc.wait(10)
            raise RuntimeError(f"{name} did not start: {(self.root / f'{name}.log').read_text()[-2000:]}")
        return proc

    def files(self, name: str, pair: KeyPair, ca: KeyPair | None = None) -> TlsFiles:
        return tls.write_files(self.root / name, name, pair, ca or self.ca)

    def host_files(self, host: str, *, address: str = "127.0.0.1") -> TlsFiles:
        """The router's files on ``host``'s folder: its key made there, its certificate for ``address``."""
        machine = LocalHost(name=host, base=str(self.root / "hosts" / host))
        machine.connect()
        folder = router_folder(f"{machine.base}/certs")
        hostcert.ensure(machine, python=sys.executable, folder=folder, ca=self.ca, name=tls.host_name(STACK, host),
                         addresses=(address,), what="Zenoh router")
        machine.put(self.ca.cert_pem, f"{folder}/ca.pem")
        return TlsFiles(ca=f"{folder}/ca.pem", cert=f"{folder}/server.pem", key=f"{folder}/server.key")

    def cloud_config(self, rt: RelayRoute, *, local_port: int) -> dict[str, Any]:
        return cloud_router(rt, listen_host="127.0.0.1", tls=self.host_files(rt.host),
                            edge_name=tls.edge_name(STACK), local_port=local_port)

    def edge_config(self, cloud: list[tuple[str, int]], *, local_port: int, ca: KeyPair | None = None,
                    routes: tuple[RelayRoute, ...] | None = None) -> dict[str, Any]:
        """The edge router's config; its access control lets each cloud router reach its route's topics
        (by default the lab's one ``gpu`` host with :func:`route`'s topics)."""
        signer = ca or self.ca
        pair = tls.edge_pair(signer, stack=STACK)
        files = self.files("edge", pair, signer)
        if ca is not None:  # an edge from another CA still trusts fogiac's CA for the cloud's certificate
            files = TlsFiles(ca=self.files("trust", pair).ca, cert=files.cert, key=files.key)
        routes = routes if routes is not None else tuple(route(port) for _, port in cloud)
        policy = [(tls.host_name(STACK, r.host), r) for r in routes]
        return edge_router(cloud, tls=files, local_port=local_port, policy=policy)

    def router(self, name: str, config: dict[str, Any], *args: str) -> subprocess.Popen:
        """``python -m fogiac.net.zenoh.router`` on ``config``, with its other ``args`` (``--stats-file``...)."""
        path = self.root / f"{name}.json"
        path.write_text(json.dumps(config, indent=1))
        return self._start(["-m", "fogiac.net.zenoh.router", str(path), *args], name)

    def node(self, name: str, port: int, *, pub: tuple[str, ...] = (), sub: tuple[str, ...] = (),
             size: int = 64) -> Path:
        out = self.root / f"{name}.jsonl"
        args = ["-m", "tests.net.zenoh.ros2node", str(port), str(out), "--size", str(size)]
        args += [a for p in pub for a in ("--pub", p)] + [a for s in sub for a in ("--sub", s)]
        self._start(args, name)
        return out

    def monitor(self, port: int, *, to_edge: tuple[str, ...], to_cloud: tuple[str, ...]) -> subprocess.Popen:
        """fogiac's edge monitor (``/fogros/latency``, ``/fogros/throughput``) on the router at ``port``."""
        args = ["-m", "fogiac.net.zenoh.monitor", f"tcp/127.0.0.1:{port}", "--period", "0.5"]
        args += [a for t in to_edge for a in ("--to-edge", t)] + [a for t in to_cloud for a in ("--to-cloud", t)]
        return self._start(args, "monitor")

    @staticmethod
    def received(out: Path, topic: str) -> int:
        return len([e for e in read_events(out) if e["event"] == "received" and e["topic"] == topic])

    def wait_received(self, out: Path, topic: str, *, count: int = 1, timeout: float = 30) -> list[dict[str, Any]]:
        def enough() -> list[dict[str, Any]] | None:
            got = [e for e in read_events(out) if e["event"] == "received" and e["topic"] == topic]
            return got if len(got) >= count else None

        return poll(enough, timeout=timeout)


def free_ports(n: int) -> list[int]:
    ports: list[int] = []
    while len(ports) < n:
        port = free_port()
        if port not in ports:
            ports.append(port)
    return ports
