"""``stratus``: a target whose platform runs the nodes itself, defined only in the tests, to show that such a
target needs no SSH, no provisioning and no supervisor of fogiac's. Its "platform" (a managed container
service, as it would be) is :mod:`.platform`: it runs each planned host as a pod of processes of its
own (the host's ROS master, its nodes and the relay's cloud end, each in a session of its own) and
keeps its own record of them. fogiac asks the target for the links the edge dials and starts only the
edge's end.

::

    platform.py   the platform: pods of processes it starts, records and stops itself
    driver.py     the lifecycle's questions: place, create (the platform's pods), reach (the links), destroy ...

It declares no ``Feature.PROVISIONS``: the lifecycle never opens a host of it.
"""

from __future__ import annotations

from fogiac.targets import TargetEntry

ENTRY = TargetEntry(name="stratus", driver="tests.plugins.stratus.driver:STRATUS")
ENTRY_POINTS = {"fogiac.targets": {"stratus": "tests.plugins.stratus:ENTRY"}}
