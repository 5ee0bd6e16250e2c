"""The cheapest EC2 catalogue type that fits a node's requirement, and the runners-up.

The ranking is the neutral catalogue's (:func:`fogiac.catalogue.cheapest`: spot nodes by the
Spot Instance Advisor's estimate, ties to the smaller machine, then the name); this is it over
the EC2 table. Pure: no network.
"""

from __future__ import annotations

from fogiac.catalogue import cheapest
from fogiac.manifest.machines import Choice, Requirement
from fogiac.targets.aws.manifest import CLOUD as AWS


def choose(req: Requirement, region: str, *, spot: bool = False) -> Choice:
    """The cheapest EC2 type in ``region`` that meets ``req``, at the spot estimate when ``spot``;
    raises :class:`~fogiac.manifest.machines.NoMachine` if none fits."""
    return cheapest(AWS.catalog, req, region, spot=spot)
