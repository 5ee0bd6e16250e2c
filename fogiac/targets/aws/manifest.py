"""The ``aws`` variant of the manifest's ``cloud:`` block, answered from the EC2 catalogue in this folder.

Regions, zones and machine types come from :mod:`.catalogue` (every commercial region, every
current and previous family, per-region offering and dated prices); a name the catalogue lacks
but the EC2 API knows (:mod:`.known`, botocore's own lists) is accepted with a one-line warning
that its cost is unknown, and a typo gets suggestions from the catalogue's facts. Named by the
``fogiac.clouds`` entry point; loading it imports no SDK and nothing of the lifecycle, and the
catalogue itself is read on first use.

The manifest's AWS-only keys and limits are this variant's too: the ``network:`` block's VPC and VPN
address ranges and flow logs (:class:`Network`), the default region, the tag limits and the reserved
``aws:`` prefix, and the node cap the hosts subnet sets (:data:`LIMITS`).
"""

from __future__ import annotations

import ipaddress
import re
import warnings
from collections.abc import Sequence
from pathlib import Path

from pydantic import Field, ValidationInfo, field_validator, model_validator

from fogiac.manifest.clouds import Limits
from fogiac.manifest.fields import _sizing
from fogiac.manifest.machines import (
    ALTERNATIVES,
    Bound,
    Choice,
    CostUnknown,
    NoMachine,
    Option,
    PriceSource,
    RankedBy,
    Requirement,
)
from fogiac.manifest.network import EGRESS_TCP, NetworkBlock
from fogiac.manifest.problems import FieldProblem
from fogiac.state import state_root
from fogiac.targets.aws import known
from fogiac.targets.aws.catalogue import (
    Arch,
    Catalogue,
    InstanceType,
    Offer,
    Source,
    load,
    not_offered,
    suggest_region,
    suggest_type,
)
from fogiac.targets.aws.catalogue import digest as catalogue_digest

DEFAULT_REGION = "us-west-2"  # a manifest without cloud.region
# AWS's tag limits per resource (50 tags, keys of 128 characters, values of 256; the aws: prefix is
# AWS's own). Nodes in one stack: the hosts subnet (a /24 at most) holds 251 machines, and a plan of
# 250 aws nodes takes seconds (Pulumi declares each instance); 1600 took 25 s and 530 MB before this cap.
LIMITS = Limits(tags=50, tag_key=128, tag_value=256, reserved=("aws:",), nodes=250)
MIN_SUBNET_PREFIX = 27  # the smallest subnet the VPC is cut into: vpc_cidr holds two of them
GPU_EXAMPLE = "g4dn.xlarge"  # named when a node sets gpu: true on a type without one
EDGE_VPN_PREFIX = (12, 22)  # the Client VPN's shortest and longest client range
SPOT_CEILING = "AWS never charges more than on-demand"
NETWORK_ITEM = "the Client VPN association"
# AWS Client VPN pricing page (aws.amazon.com/vpn/pricing), us-east-1, 2025-06: what a refreshed
# catalogue (which the EC2 APIs cannot fill in) falls back to
CLIENT_VPN_USD_PER_HOUR = {"association": 0.1, "connection": 0.05}
REFRESH = "`fogiac catalog update` refreshes the catalogue"
# A requirement without ``arch`` means x86_64: images and workloads are amd64 unless the manifest
# says arm64 (Graviton); ``gpu: true`` means a CUDA GPU, since the GPU image is NVIDIA's.
DEFAULT_ARCH: Arch = "x86_64"
NOT_CUDA = ("Radeon", "Gaudi")


_GRAVITON = re.compile(r"^(a1|[a-z]+\d+g[a-z]*)\.")  # c7g, m6gd, t4g, x2gd, im4gn, g5g ...
_BOTOCORE = Source("botocore's EC2 service model: the type exists; its hardware is not in the catalogue", "", "")


class Network(NetworkBlock):
    """The ``network:`` block with the keys only the aws target reads: the VPC's and the edge VPN's
    address ranges, and the VPC's flow logs."""

    vpc_cidr: ipaddress.IPv4Network = Field(
        default=ipaddress.IPv4Network("10.10.0.0/16"), description="VPC address range (/16 to /26)."
    )
    client_cidr: ipaddress.IPv4Network = Field(
        default=ipaddress.IPv4Network("10.200.0.0/22"),
        description="The edge's VPN address range (the target's VPN sets its limits), outside the VPC.",
    )
    egress_tcp: tuple[int, ...] = Field(
        default=(80, 443), description=EGRESS_TCP + "; DNS and time use the VPC's resolver and Amazon Time Sync, "
        "which security groups do not filter."
    )
    flow_logs: bool = Field(
        default=False, description="VPC flow logs to a CloudWatch log group that goes with the stack (billed per GB)."
    )

    @field_validator("vpc_cidr")
    @classmethod
    def _vpc(cls, value: ipaddress.IPv4Network) -> ipaddress.IPv4Network:
        if not 16 <= value.prefixlen <= MIN_SUBNET_PREFIX - 1:
            raise ValueError(
                f"{value} must be between /16 and /{MIN_SUBNET_PREFIX - 1} "
                f"(it holds two subnets of at least /{MIN_SUBNET_PREFIX})"
            )
        return value

    @field_validator("client_cidr")
    @classmethod
    def _client(cls, value: ipaddress.IPv4Network, info: ValidationInfo) -> ipaddress.IPv4Network:
        _sizing(info).check_edge_vpn_range(str(value), value.prefixlen)  # the target's VPN says what it allows
        return value

    @model_validator(mode="after")
    def _no_overlap(self) -> Network:
        if self.mode == "vpn" and self.client_cidr.overlaps(self.vpc_cidr):
            raise FieldProblem(
                f"{self.client_cidr} overlaps vpc_cidr {self.vpc_cidr}", field="client_cidr"
            )
        return self


def network_of(block: NetworkBlock) -> Network:
    """The manifest's ``network:`` block as this variant's model made it (the default provider's)."""
    assert isinstance(block, Network), type(block)
    return block


def _unpriced(what: str) -> None:
    warnings.warn(CostUnknown(f"{what}; {REFRESH}"), stacklevel=3)


def _text(bound: Bound | None) -> str | None:
    return None if bound is None else f"{bound.op}{bound.value:g}"


def spot_estimate(offer: Offer) -> float | None:
    """The spot estimate rounded as plans show it (4 decimals), at most on-demand (AWS never charges
    more; an estimate from a regional ratio can exceed it), or None."""
    if offer.spot is None:
        return None
    ceiling = offer.on_demand.usd_per_hour if offer.on_demand is not None else offer.spot.usd_per_hour
    return min(round(offer.spot.usd_per_hour, 4), ceiling)


def _label(offer: Offer, by: RankedBy) -> str:
    spec = offer.type
    gpu = f"{spec.gpus}x {spec.gpu_model}, " if spec.has_gpu else ""
    spot = spot_estimate(offer) if by == "spot" else None
    price = f"${offer.on_demand.usd_per_hour:g}/h" if offer.on_demand else "cost unknown"
    cost = price + (f", spot about ${spot:g}/h" if spot is not None else "")
    return f"{spec.name} ({gpu}{spec.vcpus} vCPU, {spec.memory_gib:g} GiB, {cost})"


def _option(offer: Offer, by: RankedBy) -> Option:
    assert offer.on_demand is not None  # search ranks only priced offers
    return Option(offer.type.name, offer.on_demand.usd_per_hour, spot_estimate(offer) if by == "spot" else None)


def cheapest(cat: Catalogue, req: Requirement, region: str, *, spot: bool = False) -> Choice:
    """The cheapest type offered in ``region`` that meets ``req`` (at the spot estimate when ``spot``),
    with the runners-up; raises :class:`NoMachine` naming the closest types when none fits."""
    by: RankedBy = "spot" if spot else "on-demand"
    gpu = req.gpu if req.gpu not in (None, False) else (True if req.gpu_memory_gib is not None else None)
    fits = cat.search(region=region, gpu=gpu, arch=req.arch or DEFAULT_ARCH, vcpus=_text(req.vcpus),
                      memory=_text(req.memory_gib), gpu_memory_gib=_text(req.gpu_memory_gib), spot=spot)
    if gpu is True:
        fits = [o for o in fits if not (o.type.gpu_model or "").startswith(NOT_CUDA)]
    elif gpu is None:  # a CPU requirement does not pay for an accelerator (Inferentia, FPGA, ...)
        fits = [o for o in fits if not o.type.gpus]
    if not fits:
        pool = cat.search(region=region, arch=req.arch or DEFAULT_ARCH, spot=spot)
        closest = sorted(pool, key=lambda o: req.miss(o.type))[:3]
        raise NoMachine(f"no instance type in {region} has {req.describe()}; closest: "
                        + (", ".join(_label(o, by) for o in closest) or "none priced there"))
    best = fits[0]
    assert best.on_demand is not None
    return Choice(machine=best.type.name, usd_per_hour=best.on_demand.usd_per_hour,
                  alternatives=tuple(_option(o, by) for o in fits[1:1 + ALTERNATIVES]),
                  chosen_for=req.describe(), ranked_by=by, spot_usd_per_hour=spot_estimate(best) if spot else None)


def client_vpn(cat: Catalogue) -> dict[str, float]:
    """The Client VPN's hourly prices (association, connection): the catalogue's, else the page's."""
    return {k: float(cat.client_vpn_usd_per_hour.get(k, v)) for k, v in CLIENT_VPN_USD_PER_HOUR.items()}


def user_catalogue() -> Path:
    """Where ``fogiac catalog update`` writes the account's own catalogue, read in place of the shipped one."""
    return state_root() / "catalogue" / "aws.json.gz"


class AwsCloud:
    """The ``cloud:`` variant (:class:`fogiac.manifest.clouds.CloudVariant`) for EC2."""

    default_region = DEFAULT_REGION
    limits = LIMITS
    network = Network

    @property
    def catalogue(self) -> Catalogue:
        """The user's refreshed catalogue when there is one, else the shipped one (each read once)."""
        own = user_catalogue()
        return load(str(own)) if own.is_file() else load()

    def catalogue_sha256(self) -> str:
        """The digest of the catalogue :attr:`catalogue` reads now (a saved plan binds it)."""
        own = user_catalogue()
        return catalogue_digest(str(own) if own.is_file() else None)

    def regions(self) -> Sequence[str]:
        return self.catalogue.regions

    def check_region(self, region: str) -> None:
        cat = self.catalogue
        if region in cat.regions:
            return
        if region in known.regions():
            _unpriced(f"{region!r} is a real AWS region the catalogue does not cover: machines there are not "
                      "checked and their cost is unknown")
            return
        near = suggest_region(cat, region)
        raise FieldProblem(f"{region!r} is not a supported region" + (f"; did you mean {near[0]!r}?" if near else ""))

    def check_zone(self, zone: str, region: str) -> None:
        if not (zone.startswith(region) and len(zone) == len(region) + 1 and zone[-1].isascii()
                and zone[-1].islower()):  # us-west-2a: the region and one letter, nothing else
            raise FieldProblem(f"{zone!r} is not a zone of {region}", field="zone")

    def check_edge_vpn_range(self, cidr: str, prefix: int) -> None:
        """The range the edge's VPN hands out: within AWS Client VPN's limits."""
        shortest, longest = EDGE_VPN_PREFIX
        if not shortest <= prefix <= longest:
            raise ValueError(f"{cidr} must be between /{shortest} and /{longest} (AWS Client VPN's limits)")

    def machine_names(self) -> Sequence[str]:
        return self.catalogue.types

    def machine(self, name: str) -> InstanceType | None:
        """The type's hardware; for a real type the catalogue lacks, what its name says (arch) and zeros."""
        spec = self.catalogue.get(name)
        if spec is None and name in known.instance_types():
            arch: Arch = "arm64" if _GRAVITON.match(name) else "x86_64"
            return InstanceType(name=name, vcpus=0, memory_gib=0.0, arch=arch, gpus=0, gpu_model=None,
                                gpu_memory_gib=0.0, accelerator_kind=None, hardware_source=_BOTOCORE)
        return spec

    def check_machine(self, name: str) -> None:
        if name in self.catalogue or name in known.instance_types():
            return
        near = suggest_type(self.catalogue, name)
        raise FieldProblem(f"{name!r} is not a known instance type"
                           + (f"; did you mean {near[0]!r}?" if near else ""))

    def check_gpu(self, name: str) -> None:
        spec = self.catalogue.get(name)
        if spec is not None and not spec.has_gpu:
            raise FieldProblem(f"{name!r} has no GPU but the node sets gpu: true; pick a GPU type such as "
                               f"{GPU_EXAMPLE!r}", field="machine")

    def choose(self, named: str | None, need: Requirement | None, region: str, *, spot: bool) -> Choice:
        cat = self.catalogue
        if named is None:
            assert need is not None
            if region not in cat.regions:
                raise NoMachine(f"the catalogue has no machines in {region} to choose from; name a type, "
                                f"or {REFRESH}")
            return cheapest(cat, need, region, spot=spot)
        if named in cat and region in cat.regions and not cat.offered(named, region):
            raise NoMachine(not_offered(cat, named, region))
        offer = cat.offer(named, region)
        if offer is None or offer.on_demand is None:
            if named in cat or named in known.instance_types():  # else its own field's error says it
                    _unpriced(f"{named} in {region}: cost unknown (the catalogue has no price there)")
            return Choice(machine=named, usd_per_hour=None, alternatives=())
        return Choice(machine=named, usd_per_hour=offer.on_demand.usd_per_hour, alternatives=())

    def prices(self) -> PriceSource:
        cat = self.catalogue
        spot = [s for s in cat.sources if "spot" in s.name.lower()]
        on_demand = [s for s in cat.sources if s not in spot and "DescribeInstanceTypes" not in s.name]
        return PriceSource(
            source="; ".join(f"{s.name} ({s.detail})" for s in on_demand),
            as_of=max((s.date for s in on_demand), default=""),
            spot_source="; ".join(f"{s.detail} ({s.name})" for s in spot),
            spot_as_of=max((s.date for s in spot), default=""),
            spot_method=("spot price = on-demand price x (1 - savings/100), rounded to 4 decimals: an estimate of a "
                         "typical recent spot price, not a quote; AWS never charges more than the on-demand price."),
            spot_ceiling=SPOT_CEILING, network_usd_per_hour=client_vpn(cat)["association"],
            network_item=NETWORK_ITEM)

    def price_note(self, name: str, region: str) -> str:
        """``$0.805/h on-demand (AWS Price List API ..., 2026-07-20)``, or that the cost is unknown."""
        price = self.catalogue.price(name, region)
        if price is None:
            return f"{name} in {region}: cost unknown"
        estimate = " (estimate)" if price.source.estimate else ""
        return (f"{name} in {region}: ${price.usd_per_hour:g}/h on-demand{estimate}, "
                f"{price.source.name} ({price.source.date})")


CLOUD = AwsCloud()
