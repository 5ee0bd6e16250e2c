"""Zenoh deployed: a router per cloud host, and on the edge a router that dials them all plus the monitor.

The Zenoh variant's answers to :class:`fogiac.net.middleware.Middleware`'s deploying half.

- Each host runs its router (``python -m fogiac.net.zenoh.router``, supervised like any service)
  before its nodes: mutual TLS for the edge on the host's middleware port, plain TCP on loopback
  at the host's own ROS port for its nodes, access control from :func:`config.cloud_router`. Its
  key is made on the host, as the relay's is (:mod:`fogiac.net.hostcert`): the stack's CA
  signs its CSR for the router's name and the address the edge dials, one certificate per host.
- Nodes get ``RMW_IMPLEMENTATION=rmw_zenoh_cpp`` and that loopback endpoint
  (``ZENOH_CONFIG_OVERRIDE``; ``FOGIAC_ZENOH_ROUTER`` for clients that are not rmw_zenoh).
- With autostop on, the host's watchdog reads the router's stats file: idle while no edge router
  is linked (nothing can cross without one).
- The edge router listens on loopback only (``edge.zenoh_router``) and dials every cloud router;
  the monitor publishes ``/fogros/latency`` and ``/fogros/throughput`` on it. ``up`` also writes
  the robot's own router's and zenoh-bridge-ros2dds's configs, pointing at that endpoint.
- One edge router (with its monitor and configs) per edge of the plan, each with its own certificate and
  Zenoh id; a cloud router accepts every edge's certificate. The edge named after the stack (today's
  manifests' only one) keeps the names it always had; any other's processes and files carry ``@<edge>``.

A fleet (``robots:``) adds per-robot access and shared nodes (:func:`fleet_document`):

- Each host's router follows a fleet file beside its certificates (``zenoh-fleet.json``, 0600): every
  robot's certificate name and edge router id and the revoked robots. Each robot may cross only its own
  namespace ``/<robot>/...``; the router process admits each robot by its certificate at its own TLS gate
  and gives it a router of its own holding its rules (:mod:`fogiac.net.zenoh.gate`). When provisioning or
  ``fogiac robot revoke|restore`` rewrites the file, only the robots changed are admitted or refused (a
  robot refused has its links closed): no service restarts, every pid stays, no other robot's link drops.
- Each shared request/reply node (its listed inputs and outputs outside every robot's namespace) gets a
  ``zenoh-fleet-<node>`` service on its host (:mod:`fogiac.net.zenoh.fleet`): robot r1's
  ``/r1/<request>`` to the node's ``/<request>``, each reply back to the robot that asked only.
- Each robot's edge router (``zenoh-edge-router@<robot>``) lets the cloud routers reach that robot's
  namespace only; a robot dropped from ``robots:`` has its edge processes stopped, the others untouched.
- A per-robot node (``serve: per_robot``) runs one instance per robot, ``node-<node>@<robot>``, with ROS 2's
  ``--ros-args -r __ns:=/<robot> -r /scan:=/<robot>/scan ...``
  (:func:`fogiac.net.zenoh.middleware.instance_args`): its topics are in the robot's namespace, so the
  namespace rules above carry robot r1's to r1's instance only and that instance's outputs to r1 only; it gets
  no fleet process, and the fleet file and router need nothing more for it.
"""

from __future__ import annotations

import hashlib
import json
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from fogiac.certs import KeyPair, load_bundle, load_or_create_bundle, write_private
from fogiac.endpoint import Endpoint
from fogiac.errors import ProvisionError
from fogiac.hostmodel import NativeRos, Service, Where, autostop_service, make_service
from fogiac.net import hostcert
from fogiac.net.replicas import groups_of, host_figures
from fogiac.net.zenoh import tls
from fogiac.net.zenoh.config import TlsFiles, cloud_router, edge_router
from fogiac.net.zenoh.gate import front_id
from fogiac.net.zenoh.middleware import ROUTER
from fogiac.net.zenoh.replicas import SUPPORTED_MATCH, replica_prefix
from fogiac.plan.model import EdgeSpec, HostSpec, Plan, Route
from fogiac.provision import supervise
from fogiac.provision.host import Host, q
from fogiac.render import render
from fogiac.state import read_json

EDGE_ROUTER = "zenoh-edge-router"
EDGE_MONITOR = "zenoh-edge-monitor"
REPLICA = "zenoh-replica"  # on a replica's host: its keys renamed under the replica's prefix
FLEET = "zenoh-fleet"  # on a fleet's host: one per shared request/reply node, zenoh-fleet-<node>
FLEET_FILE = "zenoh-fleet.json"  # a fleet's robots and revocations, in the host's certs folder
BRIDGE_NOTE = ("zenoh-bridge-ros2dds is not installed by fogiac: for a DDS robot install it on the robot and "
               "run `zenoh-bridge-ros2dds -c {path}`")


def _zid(seed: str) -> str:
    digest = hashlib.sha256(seed.encode()).hexdigest()[:32]
    return "f" + digest[1:] if digest.startswith("0") else digest  # Zenoh refuses an id with a leading 0


def router_id(stack: str, host: str) -> str:
    """A fixed Zenoh id per cloud router, so the edge can tell which host it is linked to."""
    return _zid(f"{stack}/{host}")


def linked_id(plan: Plan, host: str, edge: EdgeSpec) -> str:
    """The Zenoh id ``edge``'s router sees of ``host``'s router: the host's router's (:func:`router_id`); in a
    fleet, that of the robot's own front behind the host's TLS gate (:mod:`fogiac.net.zenoh.gate`)."""
    return front_id(router_id(plan.stack, host), edge.name) if plan.fleet else router_id(plan.stack, host)


def edge_router_id(stack: str, edge: str | None = None) -> str:
    """An edge router's fixed Zenoh id: a cloud router's stats count only the edges' as "the edge connected"
    (None: the one edge of today's manifests, with the id it always had; else ``EdgeSpec.named``)."""
    return _zid(f"{stack}/edge-router" if edge is None else f"{stack}/edge-router/{edge}")


def edge_suffix(plan: Plan, edge: EdgeSpec) -> str:
    """What an edge's processes and files carry after their names: nothing for the edge named after the stack."""
    return "" if plan.is_default_edge(edge) else f"@{edge.name}"


def local_endpoint(where: Where) -> str:
    return f"tcp/127.0.0.1:{where.master_port}"


def node_env(where: Where) -> Mapping[str, str]:
    """What rmw_zenoh_cpp reads to find the host's router: ZENOH_CONFIG_OVERRIDE over its default session
    config (rmw_zenoh 0.1.2 on humble and later, jazzy, kilted); nodes share the host's network."""
    endpoint = local_endpoint(where)
    return {"RMW_IMPLEMENTATION": "rmw_zenoh_cpp", "ZENOH_CONFIG_OVERRIDE": f'connect/endpoints=["{endpoint}"]',
            "FOGIAC_ZENOH_ROUTER": endpoint}


def native_packages(distro: str) -> tuple[str, ...]:
    """ROS 2 and its Zenoh middleware, as packages.ros.org names them."""
    return (f"ros-{distro}-ros-base", f"ros-{distro}-rmw-zenoh-cpp")


def native_ros(distro: str) -> NativeRos:
    """A ROS 2 node on a native host needs ``ros2`` and rmw_zenoh_cpp (its RMW_IMPLEMENTATION): from the
    login environment (a source build, a sourced overlay) or the distro's setup.bash, which the nodes'
    environment then sources; they come from packages.ros.org, for Ubuntu."""
    setup = f"/opt/ros/{distro}/setup.bash"
    found = (f"{{ command -v ros2 >/dev/null || . {setup} 2>/dev/null; }} && command -v ros2 >/dev/null "
             "&& ros2 pkg prefix rmw_zenoh_cpp >/dev/null 2>&1")
    packages = native_packages(distro)
    docs = f"docs.ros.org/en/{distro}/Installation/Ubuntu-Install-Debs.html"
    return NativeRos(needs=f"{setup} or ros2 on PATH, rmw_zenoh_cpp", check=f"bash -c {q(found)}",
                     packages=packages, install=render("provision/ros2_native.sh.j2", distro=distro, packages=packages),
                     by_hand=f"sudo apt-get install -y {' '.join(packages)}",
                     origin=f"packages.ros.org (apt source: {docs})", setup=setup,
                     # The official ROS images carry packages.ros.org's apt source, not rmw_zenoh_cpp.
                     image_layer=(f"RUN apt-get update && apt-get install -y --no-install-recommends {packages[1]} "
                                  "&& rm -rf /var/lib/apt/lists/*"))


def _issued(certs: Path, name: str, make: Any) -> KeyPair:
    """The edge's certificate, issued once and kept under the stack's certs folder (re-used on every ``up``)."""
    folder = certs / "zenoh"
    cert, key = folder / f"{name}.pem", folder / f"{name}.key"
    if cert.exists() and key.exists():
        return KeyPair(cert_pem=cert.read_bytes(), key_pem=key.read_bytes())
    pair: KeyPair = make()
    folder.mkdir(parents=True, exist_ok=True, mode=0o700)
    write_private(key, pair.key_pem)
    cert.write_bytes(pair.cert_pem)
    return pair


def router_folder(certs_folder: str) -> str:
    """The host's folder of its router's PEM files, under its certs folder (the relay's files stay apart)."""
    return f"{certs_folder}/zenoh"


def host_credentials(host: Host, *, python: str, folder: str, certs_dir: Path, plan: Plan, spec: HostSpec,
                     dialed: str) -> bool:
    """The router's key made on the host; the CA signs its CSR for the router's name and ``dialed``."""
    for old in (certs_dir / "zenoh").glob(f"{spec.name}@*"):  # earlier versions made the host's key here
        old.unlink()
    return hostcert.ensure(host, python=python, folder=router_folder(folder), ca=load_bundle(certs_dir).ca,
                            name=tls.host_name(plan.stack, spec.name), addresses=(dialed,), what="Zenoh router")


def host_services(plan: Plan, spec: HostSpec, where: Where, *, certs: Path) -> tuple[Service, ...]:
    ca = load_or_create_bundle(plan.stack, certs).ca
    remote = router_folder(where.layout.certs)
    files = TlsFiles(ca=f"{remote}/ca.pem", cert=f"{remote}/server.pem", key=f"{remote}/server.key")
    route = next(r for r in plan.routes if r.host == spec.name)
    listen = where.listen
    names = [tls.edge_name(plan.stack, e.named) for e in plan.edges]
    # A fleet's robots are in its fleet file, not here: a robot added or revoked changes no service file
    config = (cloud_router(route, listen_host=listen, tls=files, robots={}, local_port=where.master_port)
              if plan.fleet else
              cloud_router(route, listen_host=listen, tls=files, edge_name=names[0] if len(names) == 1 else names,
                           local_port=where.master_port))
    config["id"] = router_id(plan.stack, spec.name)
    config["listen"]["endpoints"][0] = f"tls/{listen}:{where.relay_port}"
    path, stats = f"{where.layout.env}/zenoh-router.json", router_stats(where)
    command = (f"{q(where.python)} -m fogiac.net.zenoh.router {q(path)} --stats-file {q(stats)} "
               + (f"--fleet-file {q(fleet_path(where))}" if plan.fleet else
                  " ".join(f"--edge-id {edge_router_id(plan.stack, e.named)}" for e in plan.edges)))
    router = make_service(ROUTER, plan=plan, spec=spec, where=where, command=command, check="alive",
                              python_path=where.code_root, files=(
                                  (path, json.dumps(config, indent=1, sort_keys=True), 0o600),
                                  (files.ca, ca.cert_pem.decode(), 0o644)))
    watchdog = autostop_service(plan, spec, where, stats=stats, after=ROUTER)
    renamer = replica_service(plan, spec, where, route)
    return (router,) + ((renamer,) if renamer is not None else ()) + ((watchdog,) if watchdog is not None else ())


def fleet_path(where: Where) -> str:
    """The host's fleet file (``FLEET_FILE`` in its certs folder, where provisioning writes fleet files)."""
    return f"{where.layout.certs}/{FLEET_FILE}"


def shared_pairs(plan: Plan, spec: HostSpec) -> list[tuple[str, tuple[str, ...], tuple[str, ...]]]:
    """The host's shared request/reply nodes: (node, its listed inputs outside every robot's namespace, its
    outputs likewise), the topics :mod:`fogiac.net.zenoh.fleet` carries to and from each robot's namespace. A
    topic already another node's pair is left out (one mux per topic). A per-robot node is no pair: each of its
    instances already takes its topics in its robot's namespace, which that robot alone may cross."""
    namespaces = tuple(f"/{edge.name}/" for edge in plan.edges)
    pairs: list[tuple[str, tuple[str, ...], tuple[str, ...]]] = []
    taken: set[str] = set()
    for node in plan.nodes:
        if node.host != spec.name or node.per_robot:
            continue
        requests = tuple(sorted({t for t in node.topics_in if not t.startswith(namespaces)}))
        replies = tuple(sorted({t for t in node.topics_out if not t.startswith(namespaces)}))
        if requests and replies and not set(requests + replies) & taken:
            pairs.append((node.name, requests, replies))
            taken |= set(requests + replies)
    return pairs


def fleet_document(plan: Plan, spec: HostSpec, *, revoked: tuple[str, ...] = ()) -> dict[str, Any]:
    """What a fleet's host follows (``FLEET_FILE``): each robot by its edge router certificate's common name and
    Zenoh id (its router admits each only to ``/<robot>/...``), the record's revoked robots (admitted to
    nothing), and the host's shared pairs with the robots each serves (:func:`shared_pairs`)."""
    robots = {edge.name: {"common_name": tls.edge_name(plan.stack, edge.named),
                          "zid": edge_router_id(plan.stack, edge.named)} for edge in plan.edges}
    serves = {node.name: plan.robots_of(node) for node in plan.nodes}
    return {"robots": robots, "revoked": sorted(set(revoked) & set(robots)),
            "shared": [{"node": node, "requests": list(requests), "replies": list(replies),
                        "robots": sorted(serves[node])} for node, requests, replies in shared_pairs(plan, spec)]}


def fleet_files(plan: Plan, spec: HostSpec, *, revoked: tuple[str, ...]) -> tuple[tuple[str, bytes, int], ...]:
    """A fleet's host gets its fleet file (:func:`fleet_document`); its router and fleet services follow it, so
    a robot added, removed or revoked restarts nothing. One robot's stack (``edge:``) writes none."""
    if not plan.fleet:
        return ()
    body = json.dumps(fleet_document(plan, spec, revoked=revoked), indent=2, sort_keys=True) + "\n"
    return ((FLEET_FILE, body.encode(), 0o600),)


def link_services(plan: Plan, spec: HostSpec, where: Where) -> tuple[Service, ...]:
    """A fleet's shared pairs, one ``zenoh-fleet-<node>`` each on the host's loopback router; its robots come
    from the fleet file (the command names none, so a robot added changes no service)."""
    if not plan.fleet:
        return ()
    services = []
    for node, requests, replies in shared_pairs(plan, spec):
        command = (f"{q(where.python)} -m fogiac.net.zenoh.fleet {q(local_endpoint(where))} "
                   f"--fleet-file {q(fleet_path(where))} --node {q(node)}")
        command += "".join(f" --request {q(t)}" for t in requests) + "".join(f" --reply {q(t)}" for t in replies)
        services.append(make_service(f"{FLEET}-{node}", plan=plan, spec=spec, where=where, command=command,
                                     check="alive", python_path=where.code_root, after=ROUTER))
    return tuple(services)


def replica_service(plan: Plan, spec: HostSpec, where: Where, route: Route) -> Service | None:
    """On a replica's host: its nodes' keys renamed to and from the replica's prefix, the only keys its
    router lets cross (:mod:`fogiac.net.zenoh.replicas`)."""
    if route.replica is None:
        return None
    command = (f"{q(where.python)} -m fogiac.net.zenoh.replicas cloud {q(local_endpoint(where))} --prefix "
               f"{q(replica_prefix(route.replica.group, route.replica.index))}")
    # relay.topics (direction unknown) are not renamed: a topic renamed both ways would loop on the host
    command += "".join(f" --to-cloud {q(t)}" for t in route.to_cloud)
    command += "".join(f" --to-edge {q(t)}" for t in route.to_edge)
    return make_service(REPLICA, plan=plan, spec=spec, where=where, command=command, check="alive",
                        python_path=where.code_root, after=ROUTER)


def replica_merges(plan: Plan, *, entry: str, connect: Mapping[str, str], folder: Path,
                   suffix: str = "") -> list[str]:
    """One edge merge per replicated node whose replicas came up; notes for what is missing. ``suffix``: the
    edge's (:func:`edge_suffix`), for an edge other than the one named after the stack."""
    notes = []
    for group, routes in groups_of(plan.routes).items():
        up = [r for r in routes if r.host in connect]
        if len(up) < len(routes):
            notes.append(f"node {group}: {len(up)} of {len(routes)} replicas up "
                         f"(missing: {', '.join(r.host for r in routes if r.host not in connect)})")
        if not up:
            continue
        first = up[0].replica
        assert first is not None
        if first.match != SUPPORTED_MATCH:  # validate refuses it; a plan made otherwise gets no merge that
            # would key its replies by bytes 4..12 whatever its match says
            notes.append(f"node {group}: not merged: over Zenoh replies are matched by {SUPPORTED_MATCH} only, "
                         f"not {first.match!r}")
            continue
        argv = [sys.executable, "-m", "fogiac.net.zenoh.replicas", "edge", entry, "--group", group,
                "--hedge", first.hedge, "--hedge-delay", str(first.hedge_delay_s),
                "--linked-file", str(folder / f"zenoh-edge{suffix}.stats.json"),
                "--stats-file", str(_group_stats(folder, group, suffix))]
        for r in up:
            assert r.replica is not None
            argv += ["--replica", f"{r.replica.index},{r.host},{router_id(plan.stack, r.host)}"]
        argv += [a for t in sorted(set(up[0].to_cloud)) for a in ("--to-cloud", t)]
        argv += [a for t in sorted(set(up[0].to_edge)) for a in ("--to-edge", t)]
        supervise.start(folder, f"zenoh-replicas-{group}{suffix}", argv)
    return notes


def _group_stats(folder: Path, group: str, suffix: str = "") -> Path:
    return folder / f"zenoh-replicas-{group}{suffix}.stats.json"


def router_stats(where: Where) -> str:
    """Where the host's router writes whether the edge's router is linked, which the autostop watchdog reads."""
    return f"{where.layout.run}/{ROUTER}.stats.json"


def _port(endpoint: str) -> int:
    return Endpoint.parse(endpoint).port


def edge_up(plan: Plan, *, entry: str, connect: Mapping[str, str], certs: Path, folder: Path) -> list[str]:
    """Every edge's router, monitor and configs (``entry``: the first edge's, ``up --edge-master`` or the plan's)."""
    gone = stop_gone_robots(plan, folder=folder)
    notes = [f"robot {robot}: its edge router stopped (no longer in robots:)" for robot in gone]
    for edge in plan.edges_at(entry):
        notes += _edge_up(plan, edge, connect=connect, certs=certs, folder=folder)
    return notes


def _robot_of(service: str) -> str | None:
    """The robot an edge service is for (``zenoh-edge-router@arm1``: arm1); None for the stack-named edge's."""
    _, at, robot = service.rpartition("@")
    return robot if at else None


def stop_gone_robots(plan: Plan, *, folder: Path) -> list[str]:
    """Stop the edge processes of robots the plan no longer has, the router last (what runs on it first); the
    other robots' keep running, untouched. Returns the robots stopped."""
    robots = {edge.name for edge in plan.edges}
    names = sorted(p.stem for p in folder.glob("*.pid")) if folder.exists() else []
    gone = [n for n in names if _robot_of(n) not in (None, *robots)]
    routers = [n for n in gone if n.startswith(EDGE_ROUTER + "@")]
    supervise.stop_many(folder, [n for n in gone if n not in routers])
    supervise.stop_many(folder, routers)
    return sorted({r for r in map(_robot_of, gone) if r is not None})


def robot_topic(plan: Plan, edge: EdgeSpec, topic: str) -> str | None:
    """What ``topic`` is on ``edge``'s side: as it is for one robot; for a fleet's robot in its namespace
    (``/plan_request`` -> ``/arm1/plan_request``; ``/arm1/scan`` as it is), None in another robot's."""
    if not plan.fleet or topic.startswith(f"/{edge.name}/"):
        return topic
    if topic.startswith(tuple(f"/{e.name}/" for e in plan.edges)):
        return None
    return f"/{edge.name}{topic}"


def _mine(plan: Plan, edge: EdgeSpec, topics: set[str]) -> list[str]:
    return sorted({t for t in (robot_topic(plan, edge, topic) for topic in topics) if t is not None})


def _edge_up(plan: Plan, edge: EdgeSpec, *, connect: Mapping[str, str], certs: Path, folder: Path) -> list[str]:
    entry, suffix = edge.entry, edge_suffix(plan, edge)
    role = "edge" + suffix.replace("@", "-")  # its pair's files: edge.pem, edge-<name>.pem
    ca = load_or_create_bundle(plan.stack, certs).ca
    pair = _issued(certs, role, lambda: tls.edge_pair(ca, stack=plan.stack, edge=edge.named))
    files = tls.write_files(folder / "zenoh", role, pair, ca)
    cloud = [(e.host, e.port) for e in (Endpoint.parse(address) for _, address in sorted(connect.items()))]
    policy = [(tls.host_name(plan.stack, r.host), r) for r in plan.routes if r.host in connect]
    config = edge_router(cloud, tls=files, local_port=_port(entry), policy=policy,
                         robot=edge.name if plan.fleet else None)
    config["id"] = edge_router_id(plan.stack, edge.named)
    router_file, stats = folder / f"zenoh-edge{suffix}.json", folder / f"zenoh-edge{suffix}.stats.json"
    router_file.write_text(json.dumps(config, indent=1, sort_keys=True))
    supervise.start(folder, EDGE_ROUTER + suffix, [sys.executable, "-m", "fogiac.net.zenoh.router", str(router_file),
                                                   "--stats-file", str(stats)])
    routes = [r for r in plan.routes if r.host in connect]
    to_edge = _mine(plan, edge, {t for r in routes for t in r.to_edge + r.listed})
    to_cloud = _mine(plan, edge, {t for r in routes for t in r.to_cloud})
    monitor = [sys.executable, "-m", "fogiac.net.zenoh.monitor", entry, "--stats-file",
               str(folder / f"zenoh-monitor{suffix}.stats.json")]
    monitor += [a for t in to_edge for a in ("--to-edge", t)] + [a for t in to_cloud for a in ("--to-cloud", t)]
    supervise.start(folder, EDGE_MONITOR + suffix, monitor)
    robot = folder / f"robot-router{suffix}.json5"
    robot.write_text(json.dumps({"mode": "router", "connect": {"endpoints": [entry]}}, indent=1) + "\n")
    bridge = folder / f"zenoh-bridge-ros2dds{suffix}.json5"
    bridge.write_text(json.dumps({"mode": "client", "connect": {"endpoints": [entry]}, "plugins": {"ros2dds": {
        "allow": {"publishers": [f"{t}$" for t in to_cloud], "subscribers": [f"{t}$" for t in to_edge]}}}},
        indent=1) + "\n")
    merges = replica_merges(plan, entry=entry, connect=connect, folder=folder, suffix=suffix)
    whose = f"edge {edge.name}: " if suffix else ""
    return merges + [f"{whose}edge Zenoh router on {entry} (rmw_zenoh nodes on the robot connect there), dialing "
            + ", ".join(f"tls/{a}" for a in sorted(connect.values())),
            f"robot router config (rmw_zenohd connecting to it): {robot}", BRIDGE_NOTE.format(path=bridge)]


def edge_links(plan: Plan, *, folder: Path, connect: Mapping[str, str]) -> list[dict[str, Any]]:
    """Per edge and host, its link; an edge other than the one named after the stack says its name (``edge``)."""
    links = []
    for edge in plan.edges:
        suffix = edge_suffix(plan, edge)
        linked = set((read_json(folder / f"zenoh-edge{suffix}.stats.json") or {}).get("routers", []))
        figures = {t["topic"]: t
                   for t in (read_json(folder / f"zenoh-monitor{suffix}.stats.json") or {}).get("topics", [])}
        # host_figures calls it at once, while suffix is this edge's
        replicas = host_figures(plan.routes, lambda g: read_json(_group_stats(folder, g, suffix)))  # noqa: B023
        for route in plan.routes:
            if route.host not in connect:
                continue
            seen = {t: robot_topic(plan, edge, t) for t in sorted(set(route.to_cloud + route.to_edge + route.listed))}
            mine = [{**figures[m], "direction": "in" if t in route.to_cloud else "out"}
                    for t, m in seen.items() if m is not None and m in figures]
            links.append({"host": route.host, "connect": connect[route.host],
                          "connected": linked_id(plan, route.host, edge) in linked, "topics": mine,
                          **({"edge": edge.name} if suffix else {}),
                          **({"replica": replicas[route.host]} if route.host in replicas else {})})
    return links


class ZenohDeployment:
    """Zenoh as a :class:`fogiac.net.middleware.Deployment`."""

    robot_side: tuple[str, ...] = ()  # ROS 2 has no master for fogiac to start

    def node_env(self, where: Where) -> Mapping[str, str]:
        return node_env(where)

    def native_ros(self, distro: str) -> NativeRos:
        return native_ros(distro)

    def host_services(self, plan: Plan, spec: HostSpec, where: Where, *,
                      certs: Path | None) -> tuple[Service, ...]:
        if certs is None:
            raise ProvisionError(f"{spec.name}: the Zenoh router needs the stack's certificates")
        return host_services(plan, spec, where, certs=certs)

    def link_services(self, plan: Plan, spec: HostSpec, where: Where) -> tuple[Service, ...]:
        return link_services(plan, spec, where)  # the host's router (host_services) is the link; a fleet's muxes

    def link_files(self) -> tuple[tuple[str, int], ...]:
        return ()

    link_program = ""  # the router (a host service) is the link; a fleet's muxes run fogiac's code as it does

    def host_credentials(self, host: Host, *, python: str, folder: str, certs_dir: Path, plan: Plan,
                         spec: HostSpec, dialed: str) -> bool:
        return host_credentials(host, python=python, folder=folder, certs_dir=certs_dir, plan=plan, spec=spec,
                                dialed=dialed)

    def prepare_edge(self, plan: Plan, entry: str, *, folder: Path, start: bool) -> None:
        """Nothing to check: ROS 2 has no master, and the edge router is fogiac's own."""

    def edge_up(self, plan: Plan, *, entry: str, connect: Mapping[str, str], certs: Path,
                folder: Path) -> list[str]:
        return edge_up(plan, entry=entry, connect=connect, certs=certs, folder=folder)

    def edge_links(self, plan: Plan, *, folder: Path, connect: Mapping[str, str]) -> list[dict[str, Any]]:
        return edge_links(plan, folder=folder, connect=connect)

    def edge_stats(self, plan: Plan, *, folder: Path) -> tuple[Path, ...]:
        return ()  # the edge router's stats list linked routers, not one link's state: not dated here

    deploys_fleet = True  # a fleet's robots: each its edge router and certificate, its access in the fleet file

    def fleet_files(self, plan: Plan, spec: HostSpec, *,
                    revoked: tuple[str, ...]) -> tuple[tuple[str, bytes, int], ...]:
        return fleet_files(plan, spec, revoked=revoked)


DEPLOYMENT = ZenohDeployment()
