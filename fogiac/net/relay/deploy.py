"""The relay deployed: a ROS master and the relay's cloud end on each host, one edge end per host here.

The relay variant's answers to :class:`fogiac.net.middleware.Middleware`'s deploying half. Each
host runs its own ``roscore`` (its nodes register there) and, once the nodes run, the relay's
cloud end (plus the autostop watchdog, which reads that end's stats). On the edge, one supervised
``fogiac relay edge`` per host and per edge (each robot's master, each with its own client certificate)
joins the robot's master to that host's over mutual TLS. The edge named after the stack (today's manifests'
only one) keeps the process and file names it always had; any other's carry ``@<edge>``. A fleet's host also
gets its access file (``fleet.json``: :func:`fleet_files`), which its cloud end follows without a restart.
"""

from __future__ import annotations

import json
import os
import re
import signal
import sys
import xmlrpc.client
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

from fogiac.certs import edge_identity, edge_role, load_bundle
from fogiac.errors import FogiacError
from fogiac.hostmodel import NativeRos, Service, Where, autostop_service
from fogiac.net import hostcert
from fogiac.net.relay.fleet import ACCESS_FILE, FleetAccess, PerRobot, Robot, SharedPair
from fogiac.net.relay.match import DEFAULT_MATCH
from fogiac.net.relay.services import CLOUD_END, master_service, node_env, relay_service, relay_stats
from fogiac.net.relay.tls import relay_name
from fogiac.net.replicas import groups_of, host_figures
from fogiac.plan.fleet import robot_route
from fogiac.plan.model import EdgeSpec, HostSpec, Plan, Route
from fogiac.procs import poll
from fogiac.provision import supervise
from fogiac.provision.host import Host, q
from fogiac.render import render
from fogiac.state import read_json

EDGE_MASTER = "edge-master"
CERT_FILES = (("ca.pem", 0o644),)  # the host makes its own key; see host_credentials
# The edge relay counts directions as the edge sees them (it sends "out" what the manifest calls "in");
# status shows them as the manifest says.
MANIFEST_DIRECTION = {"out": "in", "in": "out", "-": "-"}


def host_services(plan: Plan, spec: HostSpec, where: Where) -> tuple[Service, ...]:
    return (master_service(plan, spec, where),)


def link_services(plan: Plan, spec: HostSpec, where: Where) -> tuple[Service, ...]:
    watchdog = autostop_service(plan, spec, where, stats=relay_stats(where), after=CLOUD_END)
    return (relay_service(plan, spec, where),) + ((watchdog,) if watchdog is not None else ())


def _answers(uri: str) -> bool:
    try:
        reply: Any = xmlrpc.client.ServerProxy(uri).getPid("/fogiac")
    except (OSError, xmlrpc.client.Error):
        return False
    return bool(reply[0] == 1)


def _masters_up(uris: Collection[str], *, timeout: float) -> set[str]:
    """Those of ``uris`` whose master answers within ``timeout`` s, all waited for together (one deadline)."""
    up: set[str] = set()

    def every() -> bool | None:
        up.update(u for u in uris if u not in up and _answers(u))
        return True if up >= set(uris) else None

    poll(every, timeout=timeout, interval=0.2, backoff=1.0)
    return up



EDGE_ROS_HOME = "ros"  # the edge master's ROS_HOME, in the edge folder


def edge_suffix(plan: Plan, edge: EdgeSpec) -> str:
    """What an edge's processes and files carry after their names: nothing for the edge named after the stack."""
    return "" if plan.is_default_edge(edge) else f"@{edge.name}"


def prepare_edge(uri: str, *, folder: Path, start: bool, name: str = EDGE_MASTER) -> None:
    """The edge's ROS master must answer; for demos fogiac can run it (supervised as ``name``, stopped by down)."""
    prepare_edges({uri: name}, folder=folder, start=start)


def prepare_edges(masters: Mapping[str, str], *, folder: Path, start: bool) -> None:
    """:func:`prepare_edge` for several robots' masters (uri -> supervised name) at once: those that do not answer
    are started together and waited for together, so a fleet's ``up`` waits about one master's start, not one per
    robot in turn (each roscore takes a second or more to answer)."""
    answering = _masters_up(masters, timeout=0.5)
    missing = [uri for uri in masters if uri not in answering]
    if missing and not start:
        raise FogiacError(f"no ROS master answers at {missing[0]} (edge.ros_master); start roscore, "
                          "or pass --start-edge-master to let fogiac run one")
    for uri in missing:
        url = urlparse(uri)
        name = masters[uri]
        # its logs in the stack's edge folder (down removes it), not the operator's ~/.ros/log
        home = folder / (EDGE_ROS_HOME + name.removeprefix(EDGE_MASTER))
        logs = [f"ROS_HOME={home}", f"ROS_LOG_DIR={home / 'log'}"]
        argv = ["env", *logs, "roscore", "-p", str(url.port)]
        if _loopback(url.hostname):
            # rosmaster binds where ROS_IP says: loopback, not 0.0.0.0. The master alone, without roscore's
            # rosout: roscpp's XML-RPC server binds every interface whatever ROS_IP says, and through it
            # anyone on the network could point rosout at a publisher of their own.
            argv = ["env", "-u", "ROS_HOSTNAME", *logs, "ROS_IP=127.0.0.1", "rosmaster", "--core", "-p",
                    str(url.port)]
        supervise.start(folder, name, argv)
    came_up = _masters_up(missing, timeout=30)
    late = [uri for uri in missing if uri not in came_up]
    for uri in late:
        supervise.stop(folder, masters[uri])
    if late:
        raise FogiacError(f"the edge roscore did not come up at {late[0]}; see {folder / (masters[late[0]] + '.log')}")


def _loopback(host: str | None) -> bool:
    return host == "localhost" or (host or "").startswith("127.")


def _stats(folder: Path, host: str, suffix: str = "") -> Path:
    return folder / f"relay-edge-{host}{suffix}.stats.json"


def host_credentials(host: Host, *, python: str, folder: str, certs_dir: Path, plan: Plan, spec: HostSpec) -> bool:
    """The cloud end's certificate of the host's own: its key made on the host, only a CSR signed here."""
    return hostcert.ensure(host, python=python, folder=folder, ca=load_bundle(certs_dir).ca,
                            name=relay_name(plan.stack, spec.name))


def _client_argv(stack: str, edge: str | None) -> list[str]:
    """``--client`` for an edge other than the one named after the stack (whose pair is ``client``)."""
    role = edge_role(stack, edge)
    return ["--client", role] if role != "client" else []


def edge_argv(route: Route, *, stack: str, connect: str, master: str, certs: Path, stats: Path,
              edge: str | None = None) -> list[str]:
    # One ROS name per relay: a master drops a node when another registers with its name, so
    # the relays of several hosts (or several stacks, or edges) on one edge master would evict each other.
    # The server name is the host's own: another host's certificate (same CA) is refused.
    # ``edge``: whose certificate it shows (EdgeSpec.named; None: today's one edge, ``client``).
    other = f"_{edge}" if edge is not None else ""
    name = "/fogiac_relay_edge_" + re.sub(r"[^A-Za-z0-9_]", "_", f"{stack}_{route.host}{other}")
    argv = [sys.executable, "-m", "fogiac", "relay", "edge", "--connect", connect, "--master", master,
            "--certs", str(certs), "--stats-file", str(stats), "--queue-depth", str(route.queue_size),
            "--name", name, "--server-name", relay_name(stack, route.host), *_client_argv(stack, edge)]
    argv += route.policy_argv()
    if _loopback(urlparse(master).hostname):  # its XML-RPC and TCPROS sockets on loopback beside the master
        argv += ["--ros-host", "127.0.0.1"]
    compression = dict(route.compression)
    if "*" in compression:
        argv += ["--compression", compression["*"]]
    elif compression:
        argv += ["--compression", ",".join(f"{t}={alg}" for t, alg in sorted(compression.items()))]
    return argv


def _group_stats(folder: Path, group: str, suffix: str = "") -> Path:
    return folder / f"relay-replicas-{group}{suffix}.stats.json"


def replica_groups(plan: Plan) -> dict[str, list[Route]]:
    """The replicated nodes' routes, by group, in replica order."""
    return groups_of(plan.routes)


def replicas_argv(group: str, routes: list[Route], *, stack: str, connect: Mapping[str, str], master: str,
                  certs: Path, folder: Path, edge: str | None = None) -> list[str]:
    """One ``python -m fogiac.net.relay.replicas`` for a replicated node's copies that came up: one link
    each, requests fanned out, first reply wins (``fogiac.net.relay.replicas``); ``edge`` as :func:`edge_argv`."""
    first = routes[0]
    replica = first.replica
    assert replica is not None
    other = f"_{edge}" if edge is not None else ""
    suffix = f"@{edge}" if other else ""
    name = "/fogiac_relay_replicas_" + re.sub(r"[^A-Za-z0-9_]", "_", f"{stack}_{group}{other}")
    argv = [sys.executable, "-m", "fogiac.net.relay.replicas", "--group", group, "--master", master,
            "--certs", str(certs), "--stats-file", str(_group_stats(folder, group, suffix)), *_client_argv(stack, edge),
            "--queue-depth", str(first.queue_size), "--name", name, "--match", replica.match,
            "--hedge", replica.hedge, "--hedge-delay", str(replica.hedge_delay_s)]
    argv += [a for topic, name in replica.types for a in ("--type", f"{topic}={name}")]
    for route in routes:
        assert route.replica is not None
        argv += ["--replica", ",".join([str(route.replica.index), route.host, connect[route.host],
                                        relay_name(stack, route.host), str(_stats(folder, route.host, suffix))])]
    argv += first.policy_argv()
    if _loopback(urlparse(master).hostname):  # as edge_argv: its sockets on loopback beside the master
        argv += ["--ros-host", "127.0.0.1"]
    compression = dict(first.compression)
    if "*" in compression:
        argv += ["--compression", compression["*"]]
    elif compression:
        argv += ["--compression", ",".join(f"{t}={alg}" for t, alg in sorted(compression.items()))]
    return argv


def fleet_access(plan: Plan, spec: HostSpec, *, revoked: tuple[str, ...] = ()) -> FleetAccess:
    """Who may link to ``spec``'s cloud end, and for what: each robot by its certificate's identity, its own
    namespace (``/<robot>/...``, :class:`~fogiac.net.relay.fleet.Robot`) plus the listed topics of the host's
    shared nodes that serve it; ``revoked``: the record's revoked robots, refused until restored. A shared
    node without topic lists gives no robot anything beyond its namespace (whose request it answers is
    unknown), so a fleet's shared nodes list theirs. A listed topic in another robot's namespace is that
    robot's alone, whoever publishes it. A per-robot node's topics are no robot's as named (``/scan``): each
    robot's instance uses them in its own namespace, listed under ``per_robot`` (the same for every robot)."""
    names = [edge.name for edge in plan.edges]
    robots = {}
    for edge in plan.edges:
        others = tuple(f"/{name}/" for name in names if name != edge.name)
        topics = {t for node in plan.nodes if node.host == spec.name and edge.name in plan.robots_of(node)
                  and not node.per_robot for t in (*node.topics_in, *node.topics_out) if not t.startswith(others)}
        identity = edge_identity(plan.stack, edge.named)
        robots[identity] = Robot(edge.name, identity, frozenset(topics))
    per_robot = tuple(PerRobot(node.name, frozenset(node.topics_in), frozenset(node.topics_out))
                      for node in plan.nodes if node.host == spec.name and node.per_robot)
    return FleetAccess(robots, frozenset(revoked), _shared_pairs(plan, spec, names), per_robot)


def _shared_pairs(plan: Plan, spec: HostSpec, robots: list[str]) -> tuple[SharedPair, ...]:
    """The host's shared request/reply nodes (their listed inputs the requests, their outputs outside every
    robot's namespace the replies, keyed by the node's ``reply_match``), whose replies the cloud end routes to
    the robot that asked. A topic already another node's pair stays unrouted (every robot served hears it): the
    access file names each topic in one pair only."""
    namespaces = tuple(f"/{name}/" for name in robots)
    pairs: list[SharedPair] = []
    taken: set[str] = set()
    for node in plan.nodes:
        if node.host != spec.name or node.per_robot:  # a per-robot instance answers its own robot only
            continue
        requests = frozenset(t for t in node.topics_in if not t.startswith(namespaces))
        replies = frozenset(t for t in node.topics_out if not t.startswith(namespaces))
        if requests and replies and not (requests | replies) & taken:
            pairs.append(SharedPair(node.name, requests, replies, node.reply_match or DEFAULT_MATCH))
            taken |= requests | replies
    return tuple(pairs)


def fleet_files(plan: Plan, spec: HostSpec, *, revoked: tuple[str, ...]) -> tuple[tuple[str, bytes, int], ...]:
    """A fleet's host gets its access file (:func:`fleet_access`) beside its cloud end's certificates; the
    cloud end re-reads it when it changes, so a robot added, removed or revoked restarts nothing there.
    One robot's stack (``edge:``) writes none: its cloud end links its one edge as before."""
    if not plan.fleet:
        return ()
    body = json.dumps(fleet_access(plan, spec, revoked=revoked).to_json(), indent=2, sort_keys=True) + "\n"
    return ((ACCESS_FILE, body.encode(), 0o600),)


def _robot_of(service: str) -> str | None:
    """The robot an edge service is for (``relay-edge-planner@arm1``: arm1); None for the stack-named edge's."""
    _, at, robot = service.rpartition("@")
    return robot if at else None


def stop_gone_robots(plan: Plan, *, folder: Path) -> list[str]:
    """Stop the edge services of robots the plan no longer has (its links, and the demo master fogiac ran for
    it): the other robots' processes keep running, untouched; returns the services stopped."""
    robots = {edge.name for edge in plan.edges}
    names = sorted(p.stem for p in folder.glob("*.pid")) if folder.exists() else []
    gone = [n for n in names if _robot_of(n) is not None and _robot_of(n) not in robots]
    links = [n for n in gone if n.partition("@")[0] != EDGE_MASTER]
    if links:  # the links first, as down does: a master never goes before the relays registered with it
        supervise.stop_many(folder, links)
    if len(links) < len(gone):
        supervise.stop_many(folder, [n for n in gone if n not in links])
    return gone


def wake_robot(robot: str, *, folder: Path) -> list[str]:
    """SIGHUP to ``robot``'s edge ends on this machine (its links and replica groups): a restored robot's edge,
    which the cloud ends' refusals made wait up to 30 s between dials, dials at once. Returns the services
    signalled; a robot whose edge runs elsewhere finds none here and links at its next dial."""
    names = sorted(p.stem for p in folder.glob("*.pid")) if folder.exists() else []
    woken = []
    for name in names:
        if _robot_of(name) != robot or not name.startswith(("relay-edge-", "relay-replicas-")):
            continue  # the robot's demo master is no relay: SIGHUP would end it
        child = supervise.status(folder, name)["child"]
        if child is not None and supervise.pid_alive(child):
            try:
                os.kill(child, signal.SIGHUP)
            except OSError:
                continue  # ended between the look and the signal: its restart dials at once anyway
            woken.append(name)
    return woken


def edge_up(plan: Plan, *, entry: str, connect: Mapping[str, str], certs: Path, folder: Path) -> list[str]:
    """Every edge's relays (``entry``: where the first edge's master is, ``up --edge-master`` or the plan's);
    a robot's that is already running is left as it is, and a robot no longer in the plan is stopped."""
    gone = {_robot_of(name) for name in stop_gone_robots(plan, folder=folder)}
    notes = [f"robot {robot}: its edge end stopped (no longer in robots:)" for robot in sorted(r for r in gone if r)]
    for edge in plan.edges_at(entry):
        suffix = edge_suffix(plan, edge)
        for route in plan.routes:
            if route.host in connect and route.replica is None:
                mine = robot_route(plan, route, edge.name)  # its own per-robot instances' topics, in its namespace
                supervise.start(folder, f"relay-edge-{route.host}{suffix}", edge_argv(
                    mine, stack=plan.stack, connect=connect[route.host], master=edge.entry, certs=certs,
                    stats=_stats(folder, route.host, suffix), edge=edge.named))
        for group, routes in replica_groups(plan).items():
            up = [r for r in routes if r.host in connect]
            if len(up) < len(routes) and not suffix:  # said once, not per edge
                notes.append(f"node {group}: {len(up)} of {len(routes)} replicas up "
                             f"(missing: {', '.join(r.host for r in routes if r.host not in connect)})")
            if up:
                supervise.start(folder, f"relay-replicas-{group}{suffix}", replicas_argv(
                    group, up, stack=plan.stack, connect=connect, master=edge.entry, certs=certs, folder=folder,
                    edge=edge.named))
    return notes


def replica_figures(folder: Path, plan: Plan | None, suffix: str = "") -> dict[str, dict[str, Any]]:
    """host -> its replica's figures (answers won, latency, health) from its group's stats file (one edge's)."""
    return host_figures(plan.routes if plan is not None else (), lambda g: read_json(_group_stats(folder, g, suffix)))


def edge_links(folder: Path, connect: Mapping[str, str], plan: Plan | None = None) -> list[dict[str, Any]]:
    """Per edge and host, its link; an edge other than the one named after the stack says its name (``edge``)."""
    links = []
    for edge in plan.edges if plan is not None else (None,):
        suffix = edge_suffix(plan, edge) if plan is not None and edge is not None else ""
        replicas = replica_figures(folder, plan, suffix)
        for host, address in sorted(connect.items()):
            stats = read_json(_stats(folder, host, suffix)) or {}
            topics = [{**t, "direction": MANIFEST_DIRECTION.get(t.get("direction", "-"), "-")}
                      for t in stats.get("topics", [])]
            links.append({"host": host, "connect": address, **stats, "topics": topics,
                          **({"edge": edge.name} if suffix and edge is not None else {}),
                          **({"replica": replicas[host]} if host in replicas else {})})
    return links


# ROS 1 from the OS's own packages (Debian's names; Ubuntu's universe has the same).
_ROS_PACKAGES = ("ros-core", "python3-rospy", "python3-std-msgs")
_ROSPY = "import importlib.util as u, sys; sys.exit(u.find_spec('rospy') is None)"


def native_ros(distro: str) -> NativeRos:
    found = f"command -v roscore >/dev/null && command -v roslaunch >/dev/null && python3 -c {q(_ROSPY)}"
    return NativeRos(needs="roscore, roslaunch, rospy", check=found,
                     packages=_ROS_PACKAGES, probed=("ros", "roscore"),
                     install=render("provision/ros_native.sh.j2", distro=distro, packages=_ROS_PACKAGES),
                     by_hand=f"sudo apt-get install -y {' '.join(_ROS_PACKAGES)}")


class RelayDeployment:
    """The relay as a :class:`fogiac.net.middleware.Deployment`."""

    robot_side = (EDGE_MASTER,)  # the demo's roscore, when fogiac started one

    def node_env(self, where: Where) -> Mapping[str, str]:
        return node_env(where)

    def native_ros(self, distro: str) -> NativeRos:
        return native_ros(distro)

    def host_services(self, plan: Plan, spec: HostSpec, where: Where, *,
                      certs: Path | None) -> tuple[Service, ...]:
        return host_services(plan, spec, where)

    def link_services(self, plan: Plan, spec: HostSpec, where: Where) -> tuple[Service, ...]:
        return link_services(plan, spec, where)

    def link_files(self) -> tuple[tuple[str, int], ...]:
        return CERT_FILES

    link_program = "fogiac/cli/relay.py"  # the cloud end runs as `python -m fogiac relay cloud`

    def host_credentials(self, host: Host, *, python: str, folder: str, certs_dir: Path, plan: Plan,
                         spec: HostSpec, dialed: str) -> bool:
        return host_credentials(host, python=python, folder=folder, certs_dir=certs_dir, plan=plan, spec=spec)

    def prepare_edge(self, plan: Plan, entry: str, *, folder: Path, start: bool) -> None:
        masters: dict[str, str] = {}  # each robot's master (``entry``: the first's), started and waited for together
        for edge in plan.edges_at(entry):
            masters.setdefault(edge.entry, EDGE_MASTER + edge_suffix(plan, edge))
        prepare_edges(masters, folder=folder, start=start)

    def edge_up(self, plan: Plan, *, entry: str, connect: Mapping[str, str], certs: Path,
                folder: Path) -> list[str]:
        return edge_up(plan, entry=entry, connect=connect, certs=certs, folder=folder)

    def edge_links(self, plan: Plan, *, folder: Path, connect: Mapping[str, str]) -> list[dict[str, Any]]:
        return edge_links(folder, connect, plan)

    def edge_stats(self, plan: Plan, *, folder: Path) -> tuple[Path, ...]:
        return tuple(_stats(folder, route.host, edge_suffix(plan, edge)) for edge in plan.edges
                     for route in plan.routes)

    deploys_fleet = True  # a fleet's robots: each its edge end and certificate, its access in fleet.json

    def fleet_files(self, plan: Plan, spec: HostSpec, *,
                    revoked: tuple[str, ...]) -> tuple[tuple[str, bytes, int], ...]:
        return fleet_files(plan, spec, revoked=revoked)

    def wake_robot(self, plan: Plan, robot: str, *, folder: Path) -> list[str]:
        return wake_robot(robot, folder=folder)


DEPLOYMENT = RelayDeployment()
