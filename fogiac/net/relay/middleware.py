"""The relay as a :class:`fogiac.net.middleware.Middleware`: ROS 1's way across."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fogiac.manifest.schema import Edge
from fogiac.net.relay import deploy
from fogiac.net.relay.config import RELAY_PORT
from fogiac.plan.model import HostSpec, Plan
from fogiac.provision.host import Host
from fogiac.provision.services import Service, Where


@dataclass(frozen=True)
class RelayMiddleware:
    name: str = "relay"
    distros: tuple[str, ...] = ("noetic",)
    port: int = RELAY_PORT
    label: str = "fogiac relay: ROS 1 topics over one mutual-TLS link the edge opens"
    edge_side: str = "fogiac relay, edge end (dials out)"
    cloud_side: str = "fogiac relay, cloud end"
    rule_description: str = "fogiac relay (mutual TLS)"
    needs_listed_topics: bool = False  # the relay discovers topics from both masters
    credentials_first: bool = False  # the cloud end starts at link, after the nodes
    host_requirements: tuple[str, ...] = ()  # the cloud end needs fogiac's own requirements only

    def edge_entry(self, edge: Edge) -> str:
        return edge.ros_master

    def node_env(self, where: Where) -> Mapping[str, str]:
        return deploy.node_env(where)

    def host_services(self, plan: Plan, spec: HostSpec, where: Where, *, certs: Path | None) -> tuple[Service, ...]:
        return deploy.host_services(plan, spec, where)

    def link_services(self, plan: Plan, spec: HostSpec, where: Where) -> tuple[Service, ...]:
        return deploy.link_services(plan, spec, where)

    def link_files(self) -> tuple[tuple[str, int], ...]:
        return deploy.CERT_FILES

    def host_credentials(self, host: Host, *, python: str, folder: str, certs_dir: Path, plan: Plan,
                         spec: HostSpec, dialed: str) -> bool:
        return deploy.host_credentials(host, python=python, folder=folder, certs_dir=certs_dir, plan=plan, spec=spec)

    def prepare_edge(self, plan: Plan, entry: str, *, folder: Path, start: bool) -> None:
        deploy.prepare_edge(entry, folder=folder, start=start)

    def edge_up(self, plan: Plan, *, entry: str, connect: Mapping[str, str], certs: Path,
                folder: Path) -> list[str]:
        return deploy.edge_up(plan, entry=entry, connect=connect, certs=certs, folder=folder)

    def edge_links(self, plan: Plan, *, folder: Path, connect: Mapping[str, str]) -> list[dict[str, Any]]:
        return deploy.edge_links(folder, connect)


RELAY = RelayMiddleware()
