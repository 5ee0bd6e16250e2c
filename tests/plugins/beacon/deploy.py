"""The beacon deployed: a host service per cloud host and a supervised listener on the edge."""

from __future__ import annotations

import json
import shlex
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from fogiac.hostmodel import NativeRos, Service, Where, make_service
from fogiac.plan.model import HostSpec, Plan
from fogiac.provision import supervise
from fogiac.provision.host import Host
from tests.plugins.beacon.middleware import SERVICE, BeaconBlock

HERE = Path(__file__).parent
LISTENER = "beacon-listener"
STALE_S = 5.0  # a listener that wrote nothing for this long is not following anything


def settings(plan: Plan) -> BeaconBlock:
    """The manifest's ``beacon:`` block, as the plan carries it (defaults when the manifest has none)."""
    return BeaconBlock.model_validate(dict(plan.middleware_settings))


class BeaconDeployment:
    robot_side: tuple[str, ...] = ()

    def node_env(self, where: Where) -> Mapping[str, str]:
        return {"BEACON_PORT": str(where.relay_port)}

    def native_ros(self, distro: str) -> NativeRos:
        return NativeRos(needs="nothing (a lighthouse host runs no ROS)", check="true", packages=(), install="",
                         by_hand="true")

    def host_services(self, plan: Plan, spec: HostSpec, where: Where, *, certs: Path | None) -> tuple[Service, ...]:
        block = settings(plan)
        script = f"{where.layout.bin}/beacon-server.py"
        command = " ".join(shlex.quote(a) for a in (
            where.python, script, "--listen", where.listen, "--port", str(where.relay_port),
            "--interval", f"{block.interval_s:g}", "--greeting", block.greeting))
        return (make_service(SERVICE, plan=plan, spec=spec, where=where, command=command, check="alive",
                             files=((script, (HERE / "server.py").read_text(), 0o755),)),)

    def link_services(self, plan: Plan, spec: HostSpec, where: Where) -> tuple[Service, ...]:
        return ()

    def link_files(self) -> tuple[tuple[str, int], ...]:
        return ()

    link_program = ""  # no link services: the beacon's host service is the link

    def host_credentials(self, host: Host, *, python: str, folder: str, certs_dir: Path, plan: Plan,
                         spec: HostSpec, dialed: str) -> bool:
        return False  # plain TCP: nothing to sign

    def prepare_edge(self, plan: Plan, entry: str, *, folder: Path, start: bool) -> None:
        """Nothing stands for the robot here."""

    def edge_up(self, plan: Plan, *, entry: str, connect: Mapping[str, str], certs: Path,
                folder: Path) -> list[str]:
        argv = [sys.executable, str(HERE / "listener.py"), "--stats", str(folder / "beacon.stats.json")]
        argv += [a for host, address in sorted(connect.items()) for a in ("--connect", f"{host}={address}")]
        supervise.start(folder, LISTENER, argv)
        return [f"beacon listener dialing {', '.join(sorted(connect.values()))}"]

    def edge_links(self, plan: Plan, *, folder: Path, connect: Mapping[str, str]) -> list[dict[str, Any]]:
        path = folder / "beacon.stats.json"
        fresh = path.exists() and time.time() - path.stat().st_mtime < STALE_S
        seen = json.loads(path.read_text()).get("hosts", {}) if fresh else {}
        return [{"host": host, "connect": address, "connected": bool(seen.get(host, {}).get("connected")),
                 "beats": seen.get(host, {}).get("beats", 0), "interval_s": seen.get(host, {}).get("interval_s"),
                 "topics": []} for host, address in sorted(connect.items())]

    def edge_stats(self, plan: Plan, *, folder: Path) -> tuple[Path, ...]:
        return ()  # the listener's one file holds every host: it does not date a link


DEPLOYMENT = BeaconDeployment()
