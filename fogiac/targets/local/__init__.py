"""The ``local`` target: one sandbox folder and one ROS master per host, on this machine.

Demos and CI deploy the same manifest without any machine: every planned host becomes a
sandbox under the stack's state folder (:mod:`fogiac.provision.local`), reached on loopback.

:mod:`.placement` is what compile asks; :data:`.target.LOCAL` runs it. This package imports only
the registry's :class:`~fogiac.targets.TargetEntry`, so compiling loads no provisioning.
"""

from fogiac.targets import TargetEntry

ENTRY = TargetEntry(name="local", driver="fogiac.targets.local.target:LOCAL",
                    placement="fogiac.targets.local.placement:place")
