"""The namespace helper itself: isolation, links, and cleanup that survives failures."""

from __future__ import annotations

import subprocess
import sys

import pytest

from fogiac.procs import pid_alive
from tests.support.netns import NetLab, skip_reason

pytestmark = pytest.mark.root

_REASON = skip_reason()
if _REASON:
    pytest.skip(_REASON, allow_module_level=True)

_SERVE = (
    "import socket,sys;s=socket.socket();s.bind((sys.argv[1],int(sys.argv[2])));s.listen();"
    "print('ready',flush=True);c,a=s.accept();c.sendall(a[0].encode());c.close()"
)
_FETCH = (
    "import socket,sys;c=socket.create_connection((sys.argv[1],int(sys.argv[2])),timeout=5);"
    "print(c.recv(100).decode())"
)


def _names() -> set[str]:
    out = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    return {line.split()[0] for line in out.splitlines() if line.strip()}


def test_linked_namespaces_talk_and_everything_goes_away() -> None:
    with NetLab() as lab:
        a, b = lab.namespace("a"), lab.namespace("b")
        link = lab.link(a, b, a_addr="10.231.250.1/30", b_addr="10.231.250.2/30")
        server = b.popen([sys.executable, "-c", _SERVE, "10.231.250.2", "7000"],
                         stdout=subprocess.PIPE)
        assert server.stdout is not None and server.stdout.readline().strip() == "ready"
        out = a.run([sys.executable, "-c", _FETCH, "10.231.250.2", "7000"]).stdout
        assert out.strip() == "10.231.250.1"
        # A daemon that leaves the Popen's process group is still found through the namespace.
        a.run(["sh", "-c", "setsid sleep 600 >/dev/null 2>&1 &"])
        assert len(a.pids()) == 1
        made = {a.name, b.name}
        assert made <= _names()
        # The root namespace does not see the link's ends.
        root_links = subprocess.run(["ip", "-o", "link"], capture_output=True, text=True).stdout
        assert link.a_if not in root_links and link.b_if not in root_links
        daemon = a.pids()[0]
    assert not made & _names()
    assert not pid_alive(daemon)  # gone, or a zombie its new parent has yet to reap
    assert server.poll() is not None


def test_cleanup_runs_when_the_body_raises() -> None:
    with pytest.raises(RuntimeError, match=r"exited 3"):
        with NetLab() as lab:
            ns = lab.namespace("boom")
            lab.link(ns, None, a_addr="10.231.251.1/30", b_addr="10.231.251.2/30")
            name = ns.name
            ns.run(["sh", "-c", "exit 3"])
    assert name not in _names()
    root_addrs = subprocess.run(["ip", "-o", "addr"], capture_output=True, text=True).stdout
    assert "10.231.251.2" not in root_addrs


def test_per_namespace_etc_hosts() -> None:
    with NetLab() as lab:
        ns = lab.namespace("h")
        path = ns.write_etc("hosts", "10.231.252.9 endpoint.example\n")
        out = ns.run(["getent", "hosts", "endpoint.example"]).stdout
        assert out.split()[0] == "10.231.252.9"
    assert not path.exists()
