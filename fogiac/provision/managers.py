"""Who keeps services running on a host: systemd where it runs, else fogiac's own supervisor.

Why a registry: the steps say "make these services run"; how (unit files and ``systemctl``, or
``supervise.py`` and pid files) depends on the host, found out once per host.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from typing import Protocol

from fogiac.hostmodel import Layout, Service, unit_name
from fogiac.provision.host import Host, q
from fogiac.provision.probe import Facts

Health = list[tuple[str, bool, str]]  # (service, healthy, detail)

# The host's own Python 3 runs the supervisor (standard library only); the system one starts fastest.
_SUP_PYTHON = '"$(command -v /usr/bin/python3 || command -v python3)"'


class Manager(Protocol):
    name: str

    def ensure(self, host: Host, layout: Layout, services: Sequence[Service], *, restart_all: bool,
               facts: Facts | None = None) -> list[str]:
        """Make each service run its current script; return the names (re)started."""
        ...

    def prune(self, host: Host, layout: Layout, *, keep: Sequence[str], facts: Facts | None = None) -> list[str]:
        """Stop services fogiac started earlier that are no longer wanted."""
        ...

    def health(self, host: Host, layout: Layout, services: Sequence[Service], *, master: str,
               timeout: float) -> Health:
        """Wait (up to ``timeout`` in all) until each service is up and registered."""
        ...

    def stop_all(self, host: Host, layout: Layout) -> list[str]:
        ...

    def logs_command(self, layout: Layout, name: str, *, lines: int, follow: bool = False) -> str:
        """The shell command printing the last ``lines`` of service ``name``; ``follow``: and what it writes after."""
        ...


def _script_path(layout: Layout, name: str) -> str:
    return f"{layout.services}/{name}.sh"


def _current(host: Host, layout: Layout, services: Sequence[Service], status: str) -> dict[str, tuple[str, str]]:
    """{name: (script sha256 on the host, status line)} in one round trip."""
    lines = []
    for s in services:
        lines.append(f"printf '%s %s ' {q(s.name)} \"$(sha256sum {q(_script_path(layout, s.name))} 2>/dev/null "
                     f"| cut -c1-64)\"; {status.format(name=q(s.name))} 2>/dev/null || echo none")
    out = host.run("; ".join(lines), check=False).stdout
    found = {}
    for line in out.splitlines():
        name, _, rest = line.partition(" ")
        sha, _, state = rest.partition(" ")
        found[name] = (sha, state.strip())
    return found


class Supervisor:
    """``supervise.py`` (copied to the host by the runtime step) keeps each service alive."""

    name = "supervisor"

    def _sup(self, layout: Layout, action: str, name: str = "") -> str:
        return f"{_SUP_PYTHON} {q(layout.supervisor)} {action} {q(name) if name else ''} --dir {q(layout.run)}"

    def ensure(self, host: Host, layout: Layout, services: Sequence[Service], *, restart_all: bool,
               facts: Facts | None = None) -> list[str]:
        if facts is not None:
            current = {s.name: (facts.sha(_script_path(layout, s.name)) or "",
                                '"running": true' if facts.status.get(s.name, {}).get("running") else "")
                       for s in services}
        else:
            current = _current(host, layout, services, self._sup(layout, "status", "X").replace("X", "{name}", 1))
        started = []
        for s in services:
            sha, state = current.get(s.name, ("", ""))
            running = '"running": true' in state
            if sha == s.digest and running and not restart_all:
                continue
            if sha != s.digest:
                host.put(s.script.encode(), _script_path(layout, s.name), mode=0o700)
            host.run(f"{self._sup(layout, 'stop', s.name)} >/dev/null; "
                     f"{self._sup(layout, 'start', s.name)} -- /bin/bash {q(_script_path(layout, s.name))}")
            started.append(s.name)
        return started

    def prune(self, host: Host, layout: Layout, *, keep: Sequence[str], facts: Facts | None = None) -> list[str]:
        if facts is not None:
            names = [name for name, info in facts.status.items() if info.get("running")]
        else:
            out = host.run(f"cd {q(layout.run)} 2>/dev/null && ls *.pid 2>/dev/null", check=False).stdout
            names = [n.removesuffix(".pid") for n in out.split()]
        gone = [n for n in names if n not in keep]
        for name in gone:
            host.run(self._sup(layout, "stop", name))
        return gone

    def health(self, host: Host, layout: Layout, services: Sequence[Service], *, master: str,
               timeout: float) -> Health:
        specs = " ".join(f"--spec {q(s.name + '=' + s.check)}" for s in services)
        out = host.run(f"{self._sup(layout, 'health-all')} {specs} --master {q(master)} --timeout {timeout:g}",
                       check=False, timeout=timeout + 30).stdout
        results = []
        for line in out.splitlines():
            name, _, rest = line.partition(" ")
            verdict, _, detail = rest.partition(" ")
            results.append((name, verdict == "ok", detail))
        seen = {name for name, _, _ in results}
        results += [(s.name, False, "health check gave no answer") for s in services if s.name not in seen]
        return results

    def stop_all(self, host: Host, layout: Layout) -> list[str]:
        out = host.run(f"test -f {q(layout.supervisor)} && {self._sup(layout, 'stop-all')}", check=False).stdout
        return [line.split(":")[0] for line in out.splitlines() if line.endswith(": stopped")]

    def logs_command(self, layout: Layout, name: str, *, lines: int, follow: bool = False) -> str:
        return f"tail -n {lines}{' -F' if follow else ''} {q(layout.run + '/' + name + '.log')}"


class Systemd:
    """One ``fogiac-<stack>-<service>.service`` unit per service, ``Restart=on-failure``."""

    name = "systemd"

    @staticmethod
    def unit(layout: Layout, name: str) -> str:
        return unit_name(layout.stack, name)

    def ensure(self, host: Host, layout: Layout, services: Sequence[Service], *, restart_all: bool,
               facts: Facts | None = None) -> list[str]:
        status = f"systemctl is-active {unit_name(layout.stack, '{name}')}"
        current = _current(host, layout, services, status)
        started = []
        for s in services:
            unit = self.unit(layout, s.name)
            unit_path = f"/etc/systemd/system/{unit}"
            unit_same = host.run(f"sha256sum {q(unit_path)} 2>/dev/null", check=False).stdout.split()[:1] == [
                hashlib.sha256(s.unit.encode()).hexdigest()]
            sha, state = current.get(s.name, ("", ""))
            if sha == s.digest and unit_same and state == "active" and not restart_all:
                continue
            host.put(s.script.encode(), _script_path(layout, s.name), mode=0o700)
            tmp = f"{layout.tmp}/{unit}"
            host.put(s.unit.encode(), tmp)
            host.sudo(f"install -m 644 {q(tmp)} {q(unit_path)} && systemctl daemon-reload && "
                      f"systemctl enable {unit} >/dev/null 2>&1 && systemctl restart {unit}")
            started.append(s.name)
        return started

    def prune(self, host: Host, layout: Layout, *, keep: Sequence[str], facts: Facts | None = None) -> list[str]:
        """Units whose script lies in this stack's folder (earlier versions named them without the stack)."""
        wanted = {self.unit(layout, k) for k in keep}
        gone = [u for u in self._units(host, layout) if u not in wanted]
        for unit in gone:
            host.sudo(f"systemctl disable --now {unit} >/dev/null 2>&1; rm -f /etc/systemd/system/{unit}", check=False)
        prefix = f"fogiac-{layout.stack}-" if layout.stack else "fogiac-"
        return [u.removesuffix(".service").removeprefix(prefix).removeprefix("fogiac-") for u in gone]

    def _units(self, host: Host, layout: Layout) -> list[str]:
        out = host.run(f"grep -l {q(layout.services + '/')} /etc/systemd/system/fogiac-*.service 2>/dev/null",
                       check=False).stdout
        return [line.rsplit("/", 1)[-1] for line in out.split()]

    def health(self, host: Host, layout: Layout, services: Sequence[Service], *, master: str,
               timeout: float) -> Health:
        results = []
        for service in services:
            pid = f"$(systemctl show -p MainPID --value {self.unit(layout, service.name)})"
            result = host.run(f"{_SUP_PYTHON} {q(layout.supervisor)} health {q(service.name)} --dir {q(layout.run)} "
                              f"--pid {pid} --check {service.check} --master {q(master)} --timeout {timeout:g}",
                              check=False, timeout=timeout + 30)
            results.append((service.name, result.ok, result.last_line()))
        return results

    def stop_all(self, host: Host, layout: Layout) -> list[str]:
        return self.prune(host, layout, keep=())

    def logs_command(self, layout: Layout, name: str, *, lines: int, follow: bool = False) -> str:
        return f"journalctl -u {self.unit(layout, name)} -n {lines} --no-pager{' -f' if follow else ''}"


MANAGERS: dict[str, Manager] = {"systemd": Systemd(), "supervisor": Supervisor()}


def manager_for(host: Host, *, systemd: bool | None = None) -> Manager:
    """systemd when it is PID 1 (``/run/systemd/system`` exists), else the supervisor.

    A host may force one by its ``manager_name`` (the local target always uses the supervisor,
    so nothing lands outside the state directory). ``systemd`` is what a probe already saw
    (the runtime step's); None asks the host. Callers keep the answer (``HostRun.manager``).
    """
    forced = host.manager_name
    if forced is None:
        if systemd is None:
            systemd = host.run("test -d /run/systemd/system", check=False).ok
        forced = "systemd" if systemd else "supervisor"
    return MANAGERS[forced]
