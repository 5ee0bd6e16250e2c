"""``fogiac relay cloud|edge`` (the two ends of the relay) and ``fogiac certs DIR``."""

from __future__ import annotations

import logging
import signal
import threading
from pathlib import Path

import typer

from fogiac.net.relay.cloud import CloudRelay
from fogiac.net.relay.compression import parse_spec
from fogiac.net.relay.config import CloudConfig, EdgeConfig, default_ros_host, parse_hostport, policy_from_spec
from fogiac.net.relay.edge import EdgeRelay
from fogiac.net.relay.errors import RelayError
from fogiac.net.relay.tls import write_relay_lab

_MASTER = typer.Option("http://127.0.0.1:11311/", "--master", help="This side's ROS master URI.")
_CERTS = typer.Option(..., "--certs", help="Directory from `fogiac certs` (ca.pem and this end's pair).")
_ROS_HOST = typer.Option(None, "--ros-host",
                         help="Address local nodes reach the relay at (default ROS_IP/ROS_HOSTNAME).")
_STATS = typer.Option(None, "--stats-file", help="Write live figures as JSON here every second.")
_DEPTH = typer.Option(4, "--queue-depth", help="Per-topic queue length (oldest dropped first).")
_VERBOSE = typer.Option(False, "--verbose", "-v", help="Log debug detail.")
_TOPICS = typer.Option("auto", "--topics", help="auto, or /a,/b (direction from the publisher).")
_OUT = typer.Option("", "--out", help="/a,/b always sent edge -> cloud.")
_IN = typer.Option("", "--in", help="/a,/b always sent cloud -> edge.")


def _run(end: object, verbose: bool) -> None:
    """Run an end until SIGINT/SIGTERM, then withdraw its registrations."""

    logging.basicConfig(level=logging.DEBUG if verbose else logging.INFO,
                        format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    done = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: done.set())
    # SIGHUP: the cloud end reads a fleet's access file now (it is polled anyway); the edge end dials now instead
    # of at the end of its wait (a restored robot's, whose refusals made it wait up to 30 s)
    hangup = getattr(end, "reload_access", None) or getattr(end, "redial_now", None)
    if hangup is not None:
        signal.signal(signal.SIGHUP, lambda *_: hangup())
    end.start()  # type: ignore[attr-defined]
    try:
        done.wait()
    finally:
        end.stop()  # type: ignore[attr-defined]


def _common(master: str, certs: Path, ros_host: str | None, stats_file: Path | None, depth: int) -> dict:

    return {"master_uri": master, "certs": certs, "ros_host": ros_host or default_ros_host(),
            "stats_file": stats_file, "queue_depth": depth}


def register(app: typer.Typer) -> None:
    relay = typer.Typer(help="Carry ROS topics between the edge and a cloud host over mutual TLS.",
                        no_args_is_help=True)

    @relay.command("cloud")
    def cloud(listen: str = typer.Option("0.0.0.0:11411", "--listen", help="HOST:PORT to accept the edge on."),
              master: str = _MASTER, certs: Path = _CERTS, ros_host: str | None = _ROS_HOST,
              topics: str = _TOPICS, out_topics: str = _OUT, in_topics: str = _IN,
              stats_file: Path | None = _STATS, queue_depth: int = _DEPTH, verbose: bool = _VERBOSE) -> None:
        """The cloud end: wait for the edge and relay what it asks for, within the same topic policy."""

        config = CloudConfig(listen=parse_hostport(listen),
                             policy=policy_from_spec(topics, out_topics=out_topics, in_topics=in_topics),
                             **_common(master, certs, ros_host, stats_file, queue_depth))
        _run(CloudRelay(config), verbose)

    @relay.command("edge")
    def edge(connect: str = typer.Option(..., "--connect", help="The cloud end's HOST:PORT."),
             master: str = _MASTER, certs: Path = _CERTS,
             topics: str = _TOPICS, out_topics: str = _OUT, in_topics: str = _IN,
             compression: str = typer.Option("none", "--compression", help="none|zstd|lz4, or per topic /t=zstd,..."),
             server_name: str | None = typer.Option(None, "--server-name",
                                                   help="Name in the cloud's certificate (default: server.pem's)."),
             ros_host: str | None = _ROS_HOST, stats_file: Path | None = _STATS,
             queue_depth: int = _DEPTH, verbose: bool = _VERBOSE,
             client: str = typer.Option("client", "--client",
                                        help="This edge's pair under --certs (CLIENT.pem/.key): its identity."),
             name: str = typer.Option("/fogiac_relay_edge", "--name",
                                      help="The relay's ROS node name; one per relay on a master.")) -> None:
        """The edge end: dial the cloud end, keep the link up, relay topics both ways."""

        default, per_topic = parse_spec(compression)
        config = EdgeConfig(
            connect=parse_hostport(connect),
            policy=policy_from_spec(topics, out_topics=out_topics, in_topics=in_topics),
            compression=default, topic_compression=tuple(sorted(per_topic.items())), server_name=server_name,
            client=client, caller_id=name, **_common(master, certs, ros_host, stats_file, queue_depth),
        )
        _run(EdgeRelay(config), verbose)

    app.add_typer(relay, name="relay")

    @app.command("certs")
    def certs_cmd(directory: Path = typer.Argument(..., help="Where to write ca/server/client .pem and .key."),
                  stack: str = typer.Option("relay", "--stack", help="Stack name in the certificates.")) -> None:
        """Create a CA with a cloud (server) and an edge (client) certificate; keys are 0600."""
        if (directory / "ca.key").exists():
            raise RelayError(f"{directory} already holds a CA (ca.key); pick another directory")
        name = write_relay_lab(stack, directory)
        typer.echo(f"wrote ca, server ({name}) and client certificates to {directory}")
