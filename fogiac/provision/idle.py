"""Reading a host's autostop watchdog from the operator's side, the same way on every target.

Why through the host: the watchdog's verdict (:mod:`fogiac.provision.autostop`) lives in the
host's run folder, written every second; ``fogiac status`` asks the host for that file the way
provisioning reaches it (a sandbox's bash here, SSH to a lab machine or an EC2 instance), so
what it shows is what the watchdog itself concluded, not a guess from this machine. A host that
does not answer within a few seconds is reported as unreachable; status never waits on it.
"""

from __future__ import annotations

import dataclasses
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict
from pathlib import Path
from typing import Any

from fogiac.hostmodel import Layout
from fogiac.provision import autostop
from fogiac.provision.host import HostAccess, q

READ_TIMEOUT_S = 5.0  # connecting and reading, each: status stays quick when a host is gone
UNREACHABLE = "unreachable"  # the key a reading carries instead of the watchdog's state


def state_path(base: str) -> str:
    """The watchdog's state file under a host's fogiac folder (its run folder, as the supervisor's)."""
    return f"{Layout(base).run}/{autostop.STATE_FILE}"


def _quick(access: HostAccess, timeout: float) -> HostAccess:
    """The access with a short connection deadline, where the record has one (SSH's 60 s is for booting hosts)."""
    if dataclasses.is_dataclass(access) and hasattr(access, "connect_timeout"):
        return dataclasses.replace(access, connect_timeout=timeout)
    return access


def read(access: HostAccess, *, name: str, base: str, known_hosts: Path, stack: str,
         timeout: float = READ_TIMEOUT_S) -> dict[str, Any] | None:
    """The watchdog's last word on the host as a status row: its :class:`~.autostop.IdleState`
    fields, ``{"unreachable": why}`` when the host does not answer, or None when no watchdog
    ever wrote there."""
    host = _quick(access, timeout).open(name=name, known_hosts=known_hosts, stack=stack)
    try:
        host.connect()
        result = host.run(f"cat {q(state_path(base))} 2>/dev/null", check=False, timeout=timeout)
    except Exception as err:  # noqa: BLE001 -- any failure to reach the host is one line of status, never a crash
        return {UNREACHABLE: str(err).splitlines()[0] if str(err) else type(err).__name__}
    finally:
        host.close()
    state = autostop.parse_state(result.stdout) if result.ok else None
    return asdict(state) if state is not None else None


def read_all(hosts: dict[str, tuple[HostAccess, str]], *, known_hosts: Path, stack: str,
             timeout: float = READ_TIMEOUT_S) -> dict[str, dict[str, Any] | None]:
    """:func:`read` for several hosts at once (host -> (access, base)), so one slow host costs one timeout."""
    if not hosts:
        return {}
    with ThreadPoolExecutor(max_workers=min(8, len(hosts))) as pool:
        futures = {name: pool.submit(read, access, name=name, base=base, known_hosts=known_hosts, stack=stack,
                                     timeout=timeout) for name, (access, base) in hosts.items()}
        return {name: future.result() for name, future in futures.items()}
