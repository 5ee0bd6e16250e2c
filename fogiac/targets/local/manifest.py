"""The ``local`` variant of the manifest's ``cloud:`` block.

Its machines are named, sized and priced in the default provider's terms (the same manifest runs
on every target, and ``plan`` shows what the nodes would cost in the cloud), so it answers as
that variant does, found through the plug-in registry rather than imported. What it adds is what
``plan`` says of a sandbox (the optional ``plan_note`` and ``host_ports`` a variant may carry): the
machine column is not a sandbox's own size, and its relay's port is chosen at ``up``.
"""

from __future__ import annotations

from typing import Any

from fogiac.manifest.clouds import DEFAULT, variant


class Sandboxes:
    """The default variant's answers, and the plan's words for a sandbox."""

    plan_note = ("local: each host is a sandbox folder on this machine with its own ROS master; its nodes share "
                 "this machine's CPUs, GPUs and memory. The machine and its vCPUs below are what the same manifest "
                 "asks for on aws, not limits here; a sandbox costs nothing.")
    host_ports = "a free port per sandbox, chosen at the first up (up and status show it)"

    def __getattr__(self, name: str) -> Any:
        return getattr(variant(DEFAULT), name)


CLOUD = Sandboxes()
