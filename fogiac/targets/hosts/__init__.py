"""The ``hosts`` target: machines that already exist, reached over SSH (a lab GPU server is fog too).

Nodes are placed on the manifest's ``cloud.hosts`` (a node's ``host:``, else round robin);
the edge relay dials each host's address. Host keys are trusted on first use and pinned.
A lab machine is shared: each stack's ROS master and relay listen on ports of its own
(:func:`.placement.stack_ports`), beside the lab's own roscore on 11311 and any other stack.

:mod:`.placement` is what compile asks; :data:`.target.HOSTS` runs it. This package imports only
the registry's :class:`~fogiac.targets.TargetEntry`, so compiling loads no provisioning.
"""

from fogiac.targets import TargetEntry

ENTRY = TargetEntry(name="hosts", driver="fogiac.targets.hosts.target:HOSTS",
                    placement="fogiac.targets.hosts.placement:place")
