"""Throwaway network namespaces for tests that need several "hosts" on one machine.

Why: fogiac talks to cloud hosts, VPN endpoints and robots. On a test machine each of those
becomes a Linux network namespace joined by veth pairs, so real servers (OpenVPN, sshd,
roscore, the relay) run unmodified and only ever see addresses the test made itself.

Use a :class:`NetLab` as a context manager (or the :func:`netlab` generator inside a pytest
fixture); everything it creates is removed on exit, even when the test fails::

    reason = skip_reason()
    if reason:
        pytest.skip(reason)
    with NetLab() as lab:
        a, b = lab.namespace("a"), lab.namespace("b")
        lab.link(a, b, a_addr="10.231.1.1/24", b_addr="10.231.1.2/24")
        srv = b.popen(["python3", "-m", "http.server", "--bind", "10.231.1.2", "8000"])
        a.run(["curl", "http://10.231.1.2:8000/"])

- Names are unique per process (``fgt<pid>x<n>-<role>``), so parallel test runs never clash;
  addresses inside namespaces are private to them, so two runs may reuse the same ranges.
  Addresses put on the *root* side of a link (``lab.link(ns, None, ...)``) are shared with the
  whole machine: pick them from a range nothing else uses (e.g. 10.231.x.x).
- ``ip netns exec`` bind-mounts ``/etc/netns/<name>/<file>`` over ``/etc/<file>``:
  :meth:`Namespace.write_etc` uses that for per-namespace ``hosts`` or ``resolv.conf``.
- Cleanup kills every process inside each namespace (``ip netns pids``: also daemons that
  forked away from the Popen the test holds), then the process groups the lab started, then
  deletes namespaces (their veth ends go with them), root-side veths and ``/etc/netns`` files.
  Namespaces left behind by a test process that was SIGKILLed are swept by the next NetLab.
"""

from __future__ import annotations

import itertools
import os
import re
import shutil
import signal
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, Sequence

from fogiac.procs import pid_alive

_PREFIX = "fgt"
_NAME_RE = re.compile(rf"^{_PREFIX}(\d+)x\d+-")
_counter = itertools.count()


def skip_reason() -> str | None:
    """Why namespace tests cannot run here, or None when they can (root, ``ip``, netns)."""
    if os.geteuid() != 0:
        return "needs root: creates network namespaces and veth pairs"
    if shutil.which("ip") is None:
        return "needs the `ip` command (Debian package iproute2)"
    probe = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True)
    if probe.returncode != 0:
        return f"`ip netns` does not work here: {probe.stderr.strip()}"
    return None


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    result = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30)
    if check and result.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {result.stderr.strip()}")
    return result


@dataclass
class Namespace:
    """One network namespace; commands run in it through ``ip netns exec``."""

    name: str
    lab: NetLab = field(repr=False)

    def argv(self, argv: Sequence[str]) -> list[str]:
        """``argv`` wrapped to run inside this namespace."""
        return ["ip", "netns", "exec", self.name, *argv]

    def run(
        self, argv: Sequence[str], *, check: bool = True, timeout: float = 60,
        env: dict[str, str] | None = None, input: str | None = None,
    ) -> subprocess.CompletedProcess[str]:
        """Run to completion, output captured as text; ``check`` raises with stderr shown."""
        result = subprocess.run(
            self.argv(argv), capture_output=True, text=True, timeout=timeout, env=env, input=input,
            start_new_session=True,
        )
        if check and result.returncode != 0:
            raise RuntimeError(
                f"[{self.name}] {' '.join(argv)} exited {result.returncode}:\n"
                f"{result.stdout}{result.stderr}"
            )
        return result

    def popen(
        self, argv: Sequence[str], *, env: dict[str, str] | None = None,
        stdout: int | object = subprocess.DEVNULL, stderr: int | object = subprocess.STDOUT,
        cwd: str | Path | None = None, text: bool = True,
    ) -> subprocess.Popen[str]:
        """Start a background process in its own process group; the lab kills it on exit."""
        proc = subprocess.Popen(
            self.argv(argv), env=env, stdout=stdout, stderr=stderr, cwd=cwd, text=text,
            start_new_session=True, stdin=subprocess.DEVNULL,
        )
        self.lab._procs.append(proc)
        return proc

    def ip(self, *args: str) -> subprocess.CompletedProcess[str]:
        return _ip("-n", self.name, *args)

    def add_address(self, ifname: str, cidr: str) -> None:
        self.ip("addr", "add", cidr, "dev", ifname)

    def add_route(self, dest: str, *, via: str | None = None, dev: str | None = None) -> None:
        args = ["route", "add", dest]
        if via:
            args += ["via", via]
        if dev:
            args += ["dev", dev]
        self.ip(*args)

    def sysctl(self, key: str, value: str) -> None:
        """Set a per-namespace sysctl such as ``net.ipv4.ip_forward``."""
        self.run(["sysctl", "-q", "-w", f"{key}={value}"])

    def write_etc(self, filename: str, text: str) -> Path:
        """Give this namespace its own ``/etc/<filename>`` (seen by ``ip netns exec`` only)."""
        path = Path("/etc/netns") / self.name / filename
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        return path

    def pids(self) -> list[int]:
        out = _ip("netns", "pids", self.name, check=False).stdout
        return [int(p) for p in out.split()]


@dataclass(frozen=True)
class Link:
    """A veth pair: ``a_if`` sits in namespace ``a`` (None: the root namespace), ``b_if`` in ``b``."""

    a_if: str
    b_if: str


class NetLab:
    """Creates namespaces and links with unique names and removes all of them on close."""

    def __init__(self) -> None:
        self._tag = f"{_PREFIX}{os.getpid()}x{next(_counter)}"
        self._namespaces: list[Namespace] = []
        self._root_ifs: list[str] = []
        self._procs: list[subprocess.Popen[str]] = []
        self._links = itertools.count()

    def __enter__(self) -> NetLab:
        sweep_stale()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def namespace(self, role: str) -> Namespace:
        """A new namespace named ``<unique tag>-<role>`` with loopback up."""
        name = f"{self._tag}-{role}"
        _ip("netns", "add", name)
        ns = Namespace(name, self)
        self._namespaces.append(ns)
        ns.ip("link", "set", "lo", "up")
        return ns

    def link(
        self, a: Namespace | None, b: Namespace | None, *,
        a_addr: str | None = None, b_addr: str | None = None,
    ) -> Link:
        """A veth pair between ``a`` and ``b`` (None is the root namespace), up, addressed."""
        if a is None and b is None:
            raise ValueError("a link needs at least one namespace end")
        n = next(self._links)
        short = self._tag[len(_PREFIX):][-9:]
        link = Link(a_if=f"v{short}{n}a"[-15:], b_if=f"v{short}{n}b"[-15:])
        _ip("link", "add", link.a_if, "type", "veth", "peer", "name", link.b_if)
        for ns, ifname, addr in ((a, link.a_if, a_addr), (b, link.b_if, b_addr)):
            if ns is None:
                self._root_ifs.append(ifname)
                run_ip = _ip
            else:
                _ip("link", "set", ifname, "netns", ns.name)
                run_ip = ns.ip
            if addr:
                run_ip("addr", "add", addr, "dev", ifname)
            run_ip("link", "set", ifname, "up")
        return link

    def stop(self, proc: subprocess.Popen[str]) -> int | None:
        """Stop one process started with :meth:`Namespace.popen` now (its whole group)."""
        _kill_group(proc)
        return proc.returncode

    def close(self) -> None:
        """Kill every process, delete namespaces, veths and /etc/netns files; never raises."""
        for ns in self._namespaces:
            _kill_pids(ns.pids())
        for proc in self._procs:
            _kill_group(proc)
        for ns in self._namespaces:
            _ip("netns", "del", ns.name, check=False)
            shutil.rmtree(Path("/etc/netns") / ns.name, ignore_errors=True)
        for ifname in self._root_ifs:
            _ip("link", "del", ifname, check=False)
        self._namespaces.clear()
        self._root_ifs.clear()
        self._procs.clear()


def _kill_pids(pids: list[int], *, grace: float = 3.0) -> None:
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for pid in pids:
            try:
                os.kill(pid, sig)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + grace
        while time.monotonic() < deadline and any(pid_alive(p) for p in pids):
            time.sleep(0.05)
        pids = [p for p in pids if pid_alive(p)]
        if not pids:
            return


def _kill_group(proc: subprocess.Popen[str]) -> None:
    if proc.poll() is None:
        for sig in (signal.SIGTERM, signal.SIGKILL):
            try:
                os.killpg(proc.pid, sig)
            except ProcessLookupError:
                break
            try:
                proc.wait(timeout=3)
                break
            except subprocess.TimeoutExpired:
                continue
    for stream in (proc.stdout, proc.stderr):
        if stream is not None:
            stream.close()


def sweep_stale() -> list[str]:
    """Delete namespaces this helper made for test processes that no longer exist."""
    removed = []
    listing = _ip("netns", "list", check=False).stdout
    for line in listing.splitlines():
        name = line.split()[0] if line.split() else ""
        match = _NAME_RE.match(name)
        if match and not pid_alive(int(match.group(1))):
            ns = Namespace(name, NetLab())
            _kill_pids(ns.pids())
            _ip("netns", "del", name, check=False)
            shutil.rmtree(Path("/etc/netns") / name, ignore_errors=True)
            removed.append(name)
    return removed


def netlab() -> Iterator[NetLab]:
    """A pytest fixture body: ``lab = pytest.fixture(netlab)`` or ``yield from netlab()``."""
    with NetLab() as lab:
        yield lab
