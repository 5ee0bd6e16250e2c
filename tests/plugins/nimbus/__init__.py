"""``nimbus``: a second cloud, defined only in the tests, to show that a cloud is one folder and its
entry points. Its "API" is a JSON file (the machines it runs); each machine is a sandbox on this
machine, so fogiac really provisions it, connects the robot's edge to it and tears it down.

::

    catalogue.py   its machine types and regions, and the manifest ``cloud:`` variant answering from them
    placement.py   compile's question: one machine per node, priced from its catalogue
    program.py     its stack program (Pulumi resources of type ``nimbus:compute:Machine``), run by fogiac's
                   one Pulumi engine under mocks that are its API
    driver.py      the lifecycle's questions: create, reach, destroy, describe ...
"""

from __future__ import annotations

from fogiac.targets import TargetEntry

ENTRY = TargetEntry(name="nimbus", driver="tests.plugins.nimbus.driver:NIMBUS",
                    placement="tests.plugins.nimbus.placement:place")
ENTRY_POINTS = {
    "fogiac.targets": {"nimbus": "tests.plugins.nimbus:ENTRY"},
    "fogiac.clouds": {"nimbus": "tests.plugins.nimbus.catalogue:CLOUD"},
}
