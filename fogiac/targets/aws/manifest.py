"""The ``aws`` variant of the manifest's ``cloud:`` block: regions, zones and machine types as the
checked-in EC2 catalogue (:mod:`.catalog`) knows them, and the cheapest fitting type (:mod:`.machines`).

Loaded through the plug-in registry (group ``fogiac.clouds``) when a manifest is validated; it
imports the catalogue and nothing of the engine, so ``fogiac validate`` stays fast.
"""

from __future__ import annotations

from collections.abc import Sequence

from fogiac.manifest.machines import Choice, PriceSource, Requirement
from fogiac.manifest.problems import FieldProblem
from fogiac.targets.aws.catalog import InstanceType, catalog
from fogiac.targets.aws.machines import choose


class AwsCloud:
    """Answers :class:`fogiac.manifest.clouds.CloudVariant` from the EC2 catalogue."""

    name = "aws"

    def regions(self) -> Sequence[str]:
        return catalog().regions

    def check_region(self, region: str) -> None:
        regions = catalog().regions
        if region not in regions:
            raise FieldProblem(f"{region!r} is not a supported region", choices=regions)

    def check_zone(self, zone: str, region: str) -> None:
        if not (zone.startswith(region) and len(zone) == len(region) + 1):
            raise FieldProblem(f"{zone!r} is not a zone of {region}", field="zone")

    def machine_names(self) -> Sequence[str]:
        return tuple(catalog().types)

    def machine(self, name: str) -> InstanceType | None:
        return catalog().types.get(name)

    def check_machine(self, name: str) -> None:
        if name not in catalog().types:
            raise FieldProblem(f"{name!r} is not a known instance type", choices=tuple(catalog().types))

    def check_gpu(self, name: str) -> None:
        if not catalog().types[name].has_gpu:
            raise FieldProblem(
                f"{name!r} has no GPU but the node sets gpu: true; pick a GPU type such as 'g4dn.xlarge'",
                field="machine",
            )

    def choose(self, named: str | None, need: Requirement | None, region: str, *, spot: bool) -> Choice:
        if named is not None:
            return Choice(machine=named, usd_per_hour=catalog().types[named].usd_per_hour.get(region, 0.0),
                          alternatives=())
        assert need is not None
        return choose(need, region, spot=spot)

    def prices(self) -> PriceSource:
        cat = catalog()
        return PriceSource(source=cat.source, as_of=cat.as_of, spot_source=cat.spot_source, spot_as_of=cat.spot_as_of,
                           spot_method=cat.spot_method, network_usd_per_hour=cat.vpn_association_usd_per_hour,
                           network_item="the Client VPN association")


CLOUD = AwsCloud()
