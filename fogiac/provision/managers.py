"""Who keeps services running on a host: systemd where it runs, else fogiac's own supervisor.

Why a registry: the steps say "make these services run"; how (unit files and ``systemctl``, or
``supervise.py`` and pid files) depends on the host, found out once per host.
"""

from __future__ import annotations

from typing import Protocol, Sequence

from fogiac.provision.host import Host, q
from fogiac.provision.services import Layout, Service

# The host's own Python 3 runs the supervisor (standard library only); the system one starts fastest.
_SUP_PYTHON = '"$(command -v /usr/bin/python3 || command -v python3)"'


class Manager(Protocol):
    name: str

    def ensure(self, host: Host, layout: Layout, services: Sequence[Service], *, restart_all: bool) -> list[str]:
        """Make each service run its current script; return the names (re)started."""
        ...

    def prune(self, host: Host, layout: Layout, *, keep: Sequence[str]) -> list[str]:
        """Stop services fogiac started earlier that are no longer wanted."""
        ...

    def health(self, host: Host, layout: Layout, service: Service, *, master: str, timeout: float) -> tuple[bool, str]:
        ...

    def stop_all(self, host: Host, layout: Layout) -> list[str]:
        ...

    def logs_command(self, layout: Layout, name: str, *, lines: int) -> str:
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

    def ensure(self, host: Host, layout: Layout, services: Sequence[Service], *, restart_all: bool) -> list[str]:
        status = self._sup(layout, "status", "X").replace("X", "{name}", 1)
        current = _current(host, layout, services, status)
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

    def prune(self, host: Host, layout: Layout, *, keep: Sequence[str]) -> list[str]:
        names = host.run(f"cd {q(layout.run)} 2>/dev/null && ls *.pid 2>/dev/null", check=False).stdout.split()
        gone = [n.removesuffix(".pid") for n in names if n.removesuffix(".pid") not in keep]
        for name in gone:
            host.run(self._sup(layout, "stop", name))
        return gone

    def health(self, host: Host, layout: Layout, service: Service, *, master: str, timeout: float) -> tuple[bool, str]:
        result = host.run(f"{self._sup(layout, 'health', service.name)} --check {service.check} "
                          f"--master {q(master)} --timeout {timeout:g}", check=False, timeout=timeout + 30)
        return result.ok, result.last_line()

    def stop_all(self, host: Host, layout: Layout) -> list[str]:
        out = host.run(f"test -f {q(layout.supervisor)} && {self._sup(layout, 'stop-all')}", check=False).stdout
        return [line.split(":")[0] for line in out.splitlines() if line.endswith(": stopped")]

    def logs_command(self, layout: Layout, name: str, *, lines: int) -> str:
        return f"tail -n {lines} {q(layout.run + '/' + name + '.log')}"


class Systemd:
    """One ``fogiac-<service>.service`` unit per service, ``Restart=on-failure``."""

    name = "systemd"

    @staticmethod
    def unit(name: str) -> str:
        return f"fogiac-{name}.service"

    def ensure(self, host: Host, layout: Layout, services: Sequence[Service], *, restart_all: bool) -> list[str]:
        current = _current(host, layout, services, "systemctl is-active fogiac-{name}.service")
        started = []
        for s in services:
            unit_path = f"/etc/systemd/system/{self.unit(s.name)}"
            unit_same = host.run(f"sha256sum {q(unit_path)} 2>/dev/null", check=False).stdout.split()[:1] == [
                __import__("hashlib").sha256(s.unit.encode()).hexdigest()]
            sha, state = current.get(s.name, ("", ""))
            if sha == s.digest and unit_same and state == "active" and not restart_all:
                continue
            host.put(s.script.encode(), _script_path(layout, s.name), mode=0o700)
            tmp = f"{layout.tmp}/{self.unit(s.name)}"
            host.put(s.unit.encode(), tmp)
            host.sudo(f"install -m 644 {q(tmp)} {q(unit_path)} && systemctl daemon-reload && "
                      f"systemctl enable {self.unit(s.name)} >/dev/null 2>&1 && systemctl restart {self.unit(s.name)}")
            started.append(s.name)
        return started

    def prune(self, host: Host, layout: Layout, *, keep: Sequence[str]) -> list[str]:
        mine = self._units(host, layout)
        gone = [u for u in mine if u.removeprefix("fogiac-").removesuffix(".service") not in keep]
        for unit in gone:
            host.sudo(f"systemctl disable --now {unit} >/dev/null 2>&1; rm -f /etc/systemd/system/{unit}", check=False)
        return [u.removeprefix("fogiac-").removesuffix(".service") for u in gone]

    def _units(self, host: Host, layout: Layout) -> list[str]:
        out = host.run(f"grep -l {q(layout.services + '/')} /etc/systemd/system/fogiac-*.service 2>/dev/null",
                       check=False).stdout
        return [line.rsplit("/", 1)[-1] for line in out.split()]

    def health(self, host: Host, layout: Layout, service: Service, *, master: str, timeout: float) -> tuple[bool, str]:
        pid = f"$(systemctl show -p MainPID --value {self.unit(service.name)})"
        result = host.run(f"{_SUP_PYTHON} {q(layout.supervisor)} health {q(service.name)} --dir {q(layout.run)} "
                          f"--pid {pid} --check {service.check} --master {q(master)} --timeout {timeout:g}",
                          check=False, timeout=timeout + 30)
        return result.ok, result.last_line()

    def stop_all(self, host: Host, layout: Layout) -> list[str]:
        return self.prune(host, layout, keep=())

    def logs_command(self, layout: Layout, name: str, *, lines: int) -> str:
        return f"journalctl -u {self.unit(name)} -n {lines} --no-pager"


MANAGERS: dict[str, Manager] = {"systemd": Systemd(), "supervisor": Supervisor()}


def manager_for(host: Host) -> Manager:
    """systemd when it is PID 1 (``/run/systemd/system`` exists), else the supervisor; cached per host.

    A host may force one by its ``manager_name`` (the local target always uses the supervisor,
    so nothing lands outside the state directory).
    """
    cached = getattr(host, "_fogiac_manager", None)
    if cached is not None:
        return cached  # type: ignore[no-any-return]
    forced = getattr(host, "manager_name", None)
    if forced is None:
        forced = "systemd" if host.run("test -d /run/systemd/system", check=False).ok else "supervisor"
    manager = MANAGERS[forced]
    setattr(host, "_fogiac_manager", manager)
    return manager
