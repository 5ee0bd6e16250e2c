"""Frozen settings of each end, built by the CLI, the provisioner or tests."""

from __future__ import annotations

import os
import socket
from dataclasses import dataclass, field
from pathlib import Path

from fogiac.endpoint import Endpoint
from fogiac.errors import FogiacError
from fogiac.net.relay.compression import check_name
from fogiac.net.relay.errors import RelayError
from fogiac.net.relay.graph import TopicPolicy
from fogiac.plan.model import RELAY_PORT as RELAY_PORT  # the port's one definition, beside the plan's others


def default_ros_host() -> str:
    """The address other nodes reach this one at, the way rospy picks it."""
    return os.environ.get("ROS_IP") or os.environ.get("ROS_HOSTNAME") or socket.gethostname()


def parse_hostport(text: str, *, default_port: int = RELAY_PORT) -> tuple[str, int]:
    """``HOST[:PORT]`` as the relay's command line takes it (:class:`fogiac.endpoint.Endpoint` parses)."""
    try:
        found = Endpoint.parse(text, default_port=default_port)
    except FogiacError as err:
        raise RelayError(str(err)) from None
    return found.host, found.port


@dataclass(frozen=True, kw_only=True)
class EndConfig:
    master_uri: str
    certs: Path
    ros_host: str = field(default_factory=default_ros_host)
    queue_depth: int = 4  # per topic, latest-wins: deeper means more lag on a slow link
    poll_interval: float = 0.5  # seconds between getSystemState polls
    ping_interval: float = 1.0
    dead_after: float = 10.0  # seconds without a frame before the link is declared dead
    write_timeout: float = 30.0  # seconds one write may block before the peer is declared stuck
    stats_file: Path | None = None


@dataclass(frozen=True, kw_only=True)
class CloudConfig(EndConfig):
    listen: tuple[str, int] = ("0.0.0.0", RELAY_PORT)
    policy: TopicPolicy = TopicPolicy(auto=True)  # what the edge may ask for or send, as the edge's
    max_handshakes: int = 8  # connections still in TLS/HELLO; an idle one is evicted for a newer, or the newer closed
    max_per_source: int = 4  # of those, from one address
    tls_timeout: float = 3.0  # seconds a connection may take to start and finish TLS (before any certificate)
    caller_id: str = "/fogiac_relay_cloud"
    access_file: Path | None = None  # a fleet's access rules (None: ``fleet.json`` under certs; no file: one edge)
    reply_pending: int = 4096  # fleet: a robot's requests to one shared node waiting for a reply (its oldest forgotten)
    reply_expire_s: float = 60.0  # fleet: how long a request waits for its reply before it is forgotten


@dataclass(frozen=True, kw_only=True)
class EdgeConfig(EndConfig):
    connect: tuple[str, int]
    policy: TopicPolicy = TopicPolicy(auto=True)
    compression: str = "none"
    topic_compression: tuple[tuple[str, str], ...] = ()
    server_name: str | None = None
    client: str = "client"  # this edge's pair under certs (CLIENT.pem/.key): its certificate names the edge
    caller_id: str = "/fogiac_relay_edge"
    backoff_initial: float = 0.2
    backoff_max: float = 5.0
    refused_backoff_initial: float = 1.0  # the wait after the cloud end first refuses this edge (a revoked robot's),
    refused_backoff_max: float = 30.0  # doubling at each refusal up to this

    def __post_init__(self) -> None:
        check_name(self.compression)
        for _, name in self.topic_compression:
            check_name(name)

    def compression_for(self, topic: str) -> str:
        return dict(self.topic_compression).get(topic, self.compression)


def _names(text: str) -> tuple[str, ...]:
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    bad = [n for n in names if not n.startswith("/")]
    if bad:
        raise RelayError(f"topic names must be absolute (start with '/'): {', '.join(bad)}")
    return names


def policy_from_spec(topics: str = "auto", *, out_topics: str = "", in_topics: str = "") -> TopicPolicy:
    """``--topics auto`` or ``--topics /a,/b`` (direction from where the publisher is), plus
    ``--out``/``--in`` lists whose direction is fixed."""
    auto = topics.strip() == "auto"
    return TopicPolicy(
        auto=auto, topics=() if auto else _names(topics),
        out_topics=_names(out_topics), in_topics=_names(in_topics),
    )
