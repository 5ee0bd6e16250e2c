"""The ``local`` variant of the manifest's ``cloud:`` block.

Its machines are named, sized and priced in the default provider's terms (the same manifest runs
on every target, and ``plan`` shows what the nodes would cost in the cloud), so it answers as
that variant does, found through the plug-in registry rather than imported. What it adds is what
``plan`` says of a sandbox (the optional ``plan_note``, ``host_ports``, ``host_machine`` and ``host_size``
a variant may carry): the host runs on this machine, sized as nothing of its own, and its relay's port is
chosen at ``up``.
"""

from __future__ import annotations

from typing import Any

from fogiac.manifest.clouds import DEFAULT, variant


class Sandboxes:
    """The default variant's answers, and the plan's words for a sandbox."""

    plan_note = ("local: each host is a sandbox folder on this machine with its own ROS master; its nodes share "
                 "this machine's CPUs, GPUs and memory (nothing is rented: the machine in brackets is what the "
                 "same manifest asks for on aws, not a limit here); a sandbox costs nothing.")
    host_ports = "a free port per sandbox, chosen at the first up (up and status show it)"
    # The hosts table's machine cell ({machine}: what the manifest asks for elsewhere) and its sizes: nothing
    # is rented, so no size is this sandbox's own
    host_machine = "this machine (aws: {machine})"
    host_size = "shared"

    def __getattr__(self, name: str) -> Any:
        return getattr(variant(DEFAULT), name)


CLOUD = Sandboxes()
