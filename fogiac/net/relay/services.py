"""What the relay runs on each cloud host: its ROS master before the nodes, its cloud end after them.

Pure rendering, as every host service is (:mod:`fogiac.hostmodel`): the scripts and units are the
text a reviewer checks. The host's runtime says how ``roscore`` runs (in the ROS image, or the
host's own), so nothing here tests which runtime it is.
"""

from __future__ import annotations

import shlex
from collections.abc import Mapping

from fogiac.hostmodel import Service, Where, make_service, master_uri
from fogiac.net.relay.middleware import MASTER
from fogiac.net.rosenv import side_env
from fogiac.plan.fleet import shared_route
from fogiac.plan.model import HostSpec, Plan

CLOUD_END = "relay-cloud"  # the cloud end's service, whose stats the autostop watchdog reads


LOOPBACK = "127.0.0.1"


def node_env(where: Where) -> Mapping[str, str]:
    """ROS_MASTER_URI (the host's own master) and ROS_IP, loopback on every target: a host's nodes talk
    to its own master and to the relay's cloud end on the same machine only, so the master (and every
    rospy node) binds loopback and nobody on the host's network registers publishers or dials a node;
    only the relay's TLS port faces the network."""
    return side_env(side="cloud", master_uri=master_uri(where), address=LOOPBACK).env


def master_service(plan: Plan, spec: HostSpec, where: Where) -> Service:
    # In a container the master gets ROS_IP too: it advertises (and, on loopback, binds) the host's ROS address.
    command, pre = where.runtime.program(plan, spec, where, name=f"{spec.name}-{MASTER}",
                                         argv=("roscore", "-p", str(where.master_port)),
                                         env=tuple(node_env(where).items()))
    return make_service(MASTER, plan=plan, spec=spec, where=where, command=command, check="master", pre=pre)


def relay_service(plan: Plan, spec: HostSpec, where: Where) -> Service:
    route = next((r for r in plan.routes if r.host == spec.name), None)
    # A per-robot node's bare topics are left out: each robot's instance's cross by the access file (fleet.json)
    policy = " ".join(shlex.quote(arg) for arg in shared_route(plan, route).policy_argv()) if route is not None else ""
    command = (f"{shlex.quote(where.python)} -m fogiac relay cloud --listen {where.listen}:{where.relay_port} "
               f"--master {master_uri(where)} --certs {shlex.quote(where.layout.certs)} --ros-host {LOOPBACK} "
               f"--stats-file {shlex.quote(relay_stats(where))} {policy}").rstrip()
    return make_service(CLOUD_END, plan=plan, spec=spec, where=where, command=command, check="alive",
                        python_path=where.code_root, after=MASTER)


def relay_stats(where: Where) -> str:
    """Where the relay's cloud end writes its live figures, which the autostop watchdog reads."""
    return f"{where.layout.run}/{CLOUD_END}.stats.json"
