"""The cheapest EC2 catalogue type that fits a node's requirement, and the runners-up.

The ranking is :func:`fogiac.targets.aws.manifest.cheapest` over the whole catalogue (spot nodes
by the spot estimate, ties to the smaller machine, then the name). Pure: no network.
"""

from __future__ import annotations

from fogiac.manifest.machines import Choice, Requirement
from fogiac.targets.aws.manifest import CLOUD as AWS
from fogiac.targets.aws.manifest import cheapest


def choose(req: Requirement, region: str, *, spot: bool = False) -> Choice:
    """The cheapest EC2 type in ``region`` that meets ``req``, at the spot estimate when ``spot``;
    raises :class:`~fogiac.manifest.machines.NoMachine` if none fits."""
    return cheapest(AWS.catalogue, req, region, spot=spot)
