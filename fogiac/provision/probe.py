"""What a host already has, learnt in one SSH round trip before any step acts.

Why: every command over SSH costs a session (tens of milliseconds on a LAN, far more across
the internet). Steps look things up here instead of asking the host one question at a time,
so a no-op re-run costs a connection, this probe and the health check.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

from fogiac.hostmodel import Layout
from fogiac.provision.host import Host
from fogiac.provision.images import PIP_SETTINGS
from fogiac.render import render


@dataclass
class Facts:
    """Parsed probe output; paths are relative to the host's base folder."""

    base: str
    missing: list[str] = field(default_factory=list)
    flags: set[str] = field(default_factory=set)  # engine, ros, roscore, nvidia, systemd, linkprogram
    engines: list[str] = field(default_factory=list)  # container engines that answered, docker first
    inits: set[str] = field(default_factory=set)  # of those, the ones that can run a node under an init (--init)

    @property
    def has_ros(self) -> bool:
        return {"ros", "roscore"} <= self.flags
    shas: dict[str, str] = field(default_factory=dict)
    checksum_lists: dict[str, list[str]] = field(default_factory=dict)
    markers: dict[str, str] = field(default_factory=dict)
    status: dict[str, dict] = field(default_factory=dict)
    pip: dict[str, str] = field(default_factory=dict)  # the login environment's pip settings (images.PIP_SETTINGS)

    def _rel(self, path: str) -> str:
        prefix = self.base.rstrip("/") + "/"
        return path[len(prefix):] if path.startswith(prefix) else path

    def sha(self, path: str) -> str | None:
        """The file's sha256, '' when the probe saw it is absent, None when the probe did not look."""
        rel = self._rel(path)
        if rel.split("/", 1)[0] not in ("bin", "env", "services", "certs"):
            return None
        return self.shas.get(rel, "")

    def sums(self, path: str) -> str:
        return "".join(f"{line}\n" for line in self.checksum_lists.get(self._rel(path), []))

    def marker(self, path: str) -> str:
        return self.markers.get(self._rel(path), "")


def gather(host: Host, layout: Layout, *, link_program: str, engines: tuple[str, ...] = ("docker",)) -> Facts:
    """``engines``: the container engines to ask, in order of preference (each answer costs a moment);
    ``link_program``: the host's path of what the middleware's link services run ('' for none)."""
    folders = (layout.bin, layout.run, layout.services, layout.ws, layout.env, layout.state, layout.certs,
               layout.ros_home, layout.tmp)
    script = render("provision/probe.sh.j2", folders=folders, link_program=link_program, base=layout.base,
                    supervisor=layout.supervisor, run_dir=layout.run, engines=engines, pip_settings=PIP_SETTINGS)
    facts = Facts(base=layout.base)
    for line in host.run(script, check=False).stdout.splitlines():
        key, _, rest = line.partition(" ")
        if key == "missing":
            facts.missing.append(rest)
        elif key == "engine":
            facts.flags.add(key)
            facts.engines.append(rest.strip())
        elif key == "init":
            facts.inits.add(rest.strip())
        elif key in ("ros", "roscore", "nvidia", "systemd", "linkprogram"):
            facts.flags.add(key)
        elif key == "sha":
            digest, _, path = rest.partition(" ")
            facts.shas[path] = digest
        elif key == "sums":
            path, _, entry = rest.partition(" ")
            facts.checksum_lists.setdefault(path, []).append(entry)
        elif key == "marker":
            path, _, value = rest.partition(" ")
            facts.markers[path] = value.strip()
        elif key == "pip":
            name, _, value = rest.partition("=")
            facts.pip[name] = value
        elif key == "status":
            try:
                info = json.loads(rest)
            except ValueError:
                continue
            facts.status[str(info.get("name"))] = info
    return facts
