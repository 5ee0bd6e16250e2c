"""A fleet's cloud router: a TLS gate that refuses a robot by its certificate, and one Zenoh router per robot.

Zenoh 1.x reads a router's access control once, when its session opens (the interceptors are built from the
config then; ``access_control`` has no reload, the admin space's config PUT reaches only plugins), it has no
revocation list for TLS (``transport.link.tls`` takes a CA, a certificate and a key), and no API that closes
one transport. So one router session holding every robot's rules can learn a robot added or revoked only by
reopening, which drops every robot's link. Instead the router process (:mod:`fogiac.net.zenoh.router`
``--fleet-file``) holds:

- the **core** router: the host's loopback port (its nodes, the fleet processes), never reopened;
- one **front** router per admitted robot, linked to the core over loopback TCP, listening on a Unix socket in
  a folder only this process's user may enter; its access control lets the link that comes in on that socket
  (``unixsock-stream``) cross only the robot's namespace (:func:`front_access_control`), the core anything;
- the **gate** on the TLS address the edges dial: mutual TLS with the host's certificate and the stack's CA
  (Python's ``ssl``), the client certificate's common name looked up in the fleet file: a robot admitted is
  carried, byte for byte, to its front's socket; any other certificate (revoked, removed, unknown) is closed
  right after the handshake, before a byte of Zenoh crosses.

A robot added opens its front and is admitted; a robot revoked or removed is refused at once, its open links
are closed and its front closed; the other robots' links and fronts are never touched. The robots added at once
(every robot, when the process starts) open their fronts together: opening one waits about half a second. The
edge still sees mutual TLS with the host's certificate, so its own rules (by the host certificate's name) hold
as before.
"""

from __future__ import annotations

import asyncio
import hashlib
import json
import os
import shutil
import ssl
import sys
import tempfile
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fogiac.net.zenoh.config import CONNECT_RETRY, fleet_access_control, loopback_rules, namespace_rules
from fogiac.net.zenoh.errors import ZenohError

CHUNK = 65536
OPENING_AT_ONCE = 32  # fronts opened at once (threads that wait; each open holds no CPU to speak of)


@dataclass(frozen=True)
class FleetFile:
    """What the router reads of a fleet file: each robot's certificate name and edge router id, the revoked."""

    robots: dict[str, str]  # robot -> its edge router certificate's common name
    zids: dict[str, str]  # robot -> its edge router's Zenoh id
    revoked: frozenset[str]

    @property
    def admitted(self) -> dict[str, str]:
        """Common name -> robot, the robots not revoked."""
        return {cn: robot for robot, cn in self.robots.items() if robot not in self.revoked}

    @property
    def edges(self) -> list[str]:
        """The admitted robots' edge router ids: the routers whose link counts as the edge connected."""
        return [self.zids[robot] for robot in self.robots if robot not in self.revoked]


def read_fleet(fleet: Path) -> FleetFile:
    """The fleet file (no robot when it is absent); one that cannot be read raises ValueError/OSError."""
    doc = json.loads(fleet.read_text()) if fleet.exists() else {"robots": {}, "revoked": []}
    robots = doc.get("robots", {}) if isinstance(doc, dict) else None
    revoked = doc.get("revoked", []) if isinstance(doc, dict) else []
    if not isinstance(robots, dict) or not all(isinstance(r, dict) and {"common_name", "zid"} <= set(r)
                                               for r in robots.values()):
        raise ValueError(f"{fleet}: robots is not a mapping of robot -> {{common_name, zid}}")
    if not isinstance(revoked, list):
        raise ValueError(f"{fleet}: revoked is not a list of robots")
    return FleetFile(robots={str(n): str(r["common_name"]) for n, r in robots.items()},
                     zids={str(n): str(r["zid"]) for n, r in robots.items()}, revoked=frozenset(map(str, revoked)))


def front_id(core_id: str, robot: str) -> str:
    """The Zenoh id of ``robot``'s front on the router whose core has ``core_id``: fixed, so the robot's edge can
    tell which host it is linked to (:func:`fogiac.net.zenoh.deploy.edge_links`)."""
    digest = hashlib.sha256(f"{core_id}/front/{robot}".encode()).hexdigest()[:32]
    return "f" + digest[1:] if digest.startswith("0") else digest  # Zenoh refuses an id with a leading 0


def front_access_control(robot: str) -> dict[str, Any]:
    """A front's rules: the core (TCP on loopback) anything; the robot's link (the gate's Unix socket) only the
    keys of ``robot``'s namespace, both ways (:func:`fogiac.net.zenoh.config.namespace_rules`); else deny."""
    rules = loopback_rules() + namespace_rules(f"robot-{robot}", robot)
    return {"enabled": True, "default_permission": "deny", "rules": rules,
            "subjects": [{"id": "core", "link_protocols": ["tcp"], "interfaces": ["lo"]},
                         {"id": "robot", "link_protocols": ["unixsock-stream"]}],
            "policies": [{"id": "core", "rules": ["local-in", "local-out"], "subjects": ["core"]},
                         {"id": "robot", "rules": [r["id"] for r in rules if r["id"].startswith("robot-")],
                          "subjects": ["robot"]}]}


def split_config(config: dict[str, Any]) -> tuple[dict[str, Any], tuple[str, int], dict[str, str], str]:
    """A fleet cloud router's rendered config -> the core's config (its loopback endpoints, the host nodes'
    rules only), the TLS address the gate listens on, its PEM files (ca, cert, key) and the core's endpoint."""
    endpoints = list(config.get("listen", {}).get("endpoints", []))
    tls_ends = [e for e in endpoints if e.startswith("tls/")]
    local = [e for e in endpoints if not e.startswith("tls/")]
    if len(tls_ends) != 1 or not local:
        raise ValueError("a fleet's cloud router listens on one tls/ endpoint and a loopback one")
    host, _, port = tls_ends[0][len("tls/"):].rpartition(":")
    files = config.get("transport", {}).get("link", {}).get("tls", {})
    pem = {"ca": files.get("root_ca_certificate"), "cert": files.get("listen_certificate"),
           "key": files.get("listen_private_key")}
    if not all(pem.values()):
        raise ValueError("a fleet's cloud router config names no TLS CA, certificate or key")
    core = {**config, "listen": {"endpoints": local}, "access_control": fleet_access_control({})}
    return core, (host.strip("[]"), int(port)), pem, local[0]


def server_context(pem: dict[str, str]) -> ssl.SSLContext:
    """The gate's TLS: no weaker than the Zenoh link it stands in for. TLS 1.3 only, the host's certificate, a
    client certificate required and verified against the stack's CA (chain and dates); no session tickets, so
    every link is a full handshake whose certificate the gate looks up (a ticket issued before a revocation
    cannot resume past it)."""
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    context.minimum_version = ssl.TLSVersion.TLSv1_3
    context.load_cert_chain(pem["cert"], pem["key"])
    context.load_verify_locations(pem["ca"])
    context.verify_mode = ssl.CERT_REQUIRED
    context.num_tickets = 0
    return context


class FleetRouter:
    """The core, the fronts and the gate (the module docstring); :meth:`apply` takes a fleet file's robots."""

    def __init__(self, config: dict[str, Any], *, open_router: Any) -> None:
        self.core_config, self.address, self.pem, self.core_end = split_config(config)
        self.open_router = open_router
        self.core_id = str(config.get("id", ""))
        self.sockets = Path(tempfile.mkdtemp(prefix="fogiac-zenoh-fronts-"))  # 0700: only this user connects
        self.fronts: dict[str, tuple[str, Any, Path]] = {}  # robot -> (its common name, its session, its socket)
        self.admitted: dict[str, str] = {}  # common name -> robot; replaced whole, read by the gate's thread
        self.links: dict[str, set[asyncio.StreamWriter]] = {}  # robot -> the gate's open connections for it
        self.refused = 0
        self.told: set[str] = set()  # the certificates whose refusal was logged since the fleet last changed
        self.opened = 0
        self.core: Any = None
        self.server: asyncio.Server | None = None
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, name="zenoh-gate", daemon=True)

    def start(self) -> None:
        self.core = self.open_router(self.core_config)
        self.thread.start()
        future = asyncio.run_coroutine_threadsafe(
            asyncio.start_server(self._gate, self.address[0], self.address[1], ssl=server_context(self.pem),
                                 ssl_handshake_timeout=10), self.loop)
        self.server = future.result(30)

    def apply(self, fleet: FleetFile) -> list[str]:
        """Admit, open, refuse and close so that exactly ``fleet``'s admitted robots are carried; the robots whose
        certificate name stays admitted are not touched. What changed, one line each."""
        admitted = fleet.admitted
        self.told = set()
        wanted = {robot: cn for cn, robot in admitted.items()}
        changes = []
        kept = {robot for robot, (cn, _, _) in self.fronts.items() if wanted.get(robot) == cn}
        for robot in sorted(set(self.fronts) - kept):
            self.admitted = {cn: r for cn, r in self.admitted.items() if r != robot}  # refused from now on
            asyncio.run_coroutine_threadsafe(self._cut(robot), self.loop).result(30)
            _, session, sock = self.fronts.pop(robot)
            session.close()
            sock.unlink(missing_ok=True)
            changes.append(f"robot {robot}: refused, its links closed")
        adding = sorted(set(wanted) - set(self.fronts))
        for robot, (session, sock) in self._open_fronts(adding).items():
            self.fronts[robot] = (wanted[robot], session, sock)
        self.admitted = {**self.admitted, **{wanted[robot]: robot for robot in adding}}
        changes += [f"robot {robot}: admitted" for robot in adding]
        return changes

    def _open_fronts(self, robots: list[str]) -> dict[str, tuple[Any, Path]]:
        """``robots``' fronts, opened all at once: opening one waits about half a second (Zenoh's scouting delay,
        idle time, not CPU), so a fleet of 32 opened one after another took 16 s to carry its last robot. All
        or none: if one does not open, the others opened with it are closed (never admitted) and the error
        names the robot."""
        if not robots:
            return {}
        socks = {}
        for robot in robots:
            self.opened += 1
            socks[robot] = self.sockets / f"front{self.opened}.sock"
        configs = {robot: self._front_config(robot, sock) for robot, sock in socks.items()}
        with ThreadPoolExecutor(min(len(robots), OPENING_AT_ONCE), thread_name_prefix="zenoh-front") as pool:
            futures = {robot: pool.submit(self.open_router, config) for robot, config in configs.items()}
        opened, failed = {}, {}
        for robot, future in futures.items():
            try:
                opened[robot] = future.result()
            except Exception as err:  # any error: the others opened with it are closed before it is raised
                failed[robot] = err
        if not failed:
            return {robot: (session, socks[robot]) for robot, session in opened.items()}
        for robot, session in opened.items():
            session.close()
            socks[robot].unlink(missing_ok=True)
        if bug := next((err for err in failed.values() if not isinstance(err, ZenohError)), None):
            raise bug
        raise ZenohError("; ".join(f"robot {robot}'s router behind the gate did not open ({err})"
                                   for robot, err in failed.items())
                         + (f"; the {len(opened)} opened with it closed" if opened else ""))

    def refresh(self) -> None:
        """Touch the fronts' folder and sockets: systemd-tmpfiles deletes what in ``/tmp`` is not modified for
        10 days (a socket is not, by being connected to), and a front whose socket is gone admits no new link."""
        for path in (self.sockets, *(sock for _, _, sock in self.fronts.values())):
            try:
                os.utime(path, follow_symlinks=False)
            except OSError:
                pass  # a front's socket not made yet

    def _front_config(self, robot: str, sock: Path) -> dict[str, Any]:
        config: dict[str, Any] = {
            "mode": "router", "listen": {"endpoints": [f"unixsock-stream/{sock}"]},
            "connect": {"endpoints": [self.core_end], "timeout_ms": -1, "exit_on_failure": False,
                        "retry": dict(CONNECT_RETRY)},
            "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
            "adminspace": {"enabled": False}, "access_control": front_access_control(robot)}
        if self.core_id:
            config["id"] = front_id(self.core_id, robot)
        return config

    def routers(self) -> list[str]:
        """The routers linked to the core or a front, other than this process's own: the edges' (and any other
        router on the host's loopback port)."""
        sessions = [self.core] + [s for _, s, _ in self.fronts.values()]
        own = {str(s.info.zid()) for s in sessions}
        return sorted({str(z) for s in sessions for z in s.info.routers_zid()} - own)

    async def _gate(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        cert = writer.get_extra_info("peercert") or {}
        names = [v for rdn in cert.get("subject", ()) for k, v in rdn if k == "commonName"]
        robot = self.admitted.get(names[0]) if len(names) == 1 else None
        front = self.fronts.get(robot) if robot is not None else None
        if robot is None or front is None:
            self.refused += 1
            name = names[0] if names else "a certificate without a name"
            if name not in self.told:  # once per certificate until the fleet changes: an edge redials every 2 s
                self.told.add(name)
                print(f"refused a link from {name}: not an admitted robot's", file=sys.stderr, flush=True)
            writer.transport.abort()
            return
        try:
            inner_r, inner_w = await asyncio.open_unix_connection(str(front[2]))
        except OSError:
            writer.transport.abort()
            return
        if self.admitted.get(names[0]) != robot:  # refused while its front's socket was being dialled
            for w in (writer, inner_w):
                w.transport.abort()
            return
        self.links.setdefault(robot, set()).update((writer, inner_w))
        try:
            await asyncio.gather(_pump(reader, inner_w), _pump(inner_r, writer))
        finally:
            for w in (writer, inner_w):
                self.links.get(robot, set()).discard(w)
                w.transport.abort()

    async def _cut(self, robot: str) -> None:
        for writer in self.links.pop(robot, set()):
            writer.transport.abort()

    def close(self) -> None:
        """Stop admitting, then close every router. The sockets' folder goes first, so that a process killed
        while closing (a supervisor's grace run out) leaves nothing in /tmp."""
        shutil.rmtree(self.sockets, ignore_errors=True)
        if self.server is not None:
            self.loop.call_soon_threadsafe(self.server.close)
        for robot in list(self.fronts):
            _, session, _ = self.fronts.pop(robot)
            session.close()
        if self.core is not None:
            self.core.close()
        self.loop.call_soon_threadsafe(self.loop.stop)


async def _pump(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
    """Copy until either side closes, then close the other's writing half (its link then ends too)."""
    try:
        while data := await reader.read(CHUNK):
            writer.write(data)
            await writer.drain()
    except (OSError, ssl.SSLError, asyncio.IncompleteReadError):
        pass
    finally:
        writer.transport.abort()
