"""``fogiac catalog`` (search the EC2 catalogue, cheapest first) and ``fogiac catalog update``
(rebuild it from AWS's own APIs with the user's credentials).

Thin: parses, asks :mod:`.catalogue` or :mod:`.refresh`, prints. The refreshed catalogue is written
to the state folder (:func:`.manifest.user_catalogue`), where the aws ``cloud:`` variant reads it
in place of the shipped one. The aws target contributes these commands (plug-in group
``fogiac.commands``); the CLI imports no target.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import typer

from fogiac.errors import FogiacError
from fogiac.tables import console, table
from fogiac.targets.aws import api, known, refresh
from fogiac.targets.aws.catalogue import Arch, Catalogue, Offer, suggest_region
from fogiac.targets.aws.manifest import CLOUD, spot_estimate, user_catalogue

_REGION = typer.Option("us-east-1", "--region", help="The region to search.")


def _row(offer: Offer) -> tuple[str, ...]:
    spec, price, spot = offer.type, offer.on_demand, spot_estimate(offer)
    gpu = f"{spec.gpus}x {spec.gpu_model}" if spec.gpus else "-"
    when = f"{price.source.date}{' est.' if price.source.estimate else ''}" if price else "-"
    return (spec.name, str(spec.vcpus), f"{spec.memory_gib:g}", spec.arch, gpu,
            f"{price.usd_per_hour:.4f}" if price else "unknown", f"{spot:.4f}" if spot is not None else "-", when)


def _typo(cat: Catalogue, region: str) -> FogiacError:
    near = suggest_region(cat, region)
    return FogiacError(f"--region {region!r} is not an AWS region" + (f"; did you mean {near[0]!r}?" if near else ""))


def _searchable(cat: Catalogue, region: str) -> None:
    """Refuse a region the catalogue cannot answer for: a typo (with the nearest name), or a real region
    it does not cover (saying how to fill it); an empty table with exit 0 read as "nothing fits"."""
    if region in cat.regions:
        return
    if region in known.regions():
        raise FogiacError(f"--region {region!r}: the catalogue does not cover this AWS region (no machines, no "
                          f"prices); `fogiac catalog update --region {region}` reads it with your credentials")
    raise _typo(cat, region)


def register(app: typer.Typer) -> None:
    """Add ``fogiac catalog`` to the CLI (the ``fogiac.commands`` entry point ``catalog`` names this module)."""
    app.add_typer(commands(), name="catalog")


def commands() -> typer.Typer:
    """``fogiac catalog`` and its ``update``."""
    cat = typer.Typer(help="Search the EC2 catalogue (cheapest first), or refresh it from AWS.")

    @cat.callback(invoke_without_command=True)
    def search(ctx: typer.Context, region: str = _REGION,
               gpu: str | None = typer.Option(None, "--gpu", help="A GPU model (L4, A10G) or 'any'."),
               arch: str | None = typer.Option(None, "--arch", help="x86_64 or arm64."),
               vcpus: str | None = typer.Option(None, "--vcpus", help="A bound such as '>=8'."),
               memory: str | None = typer.Option(None, "--memory", help="GiB, a bound such as '>=16'."),
               spot: bool = typer.Option(False, "--spot", help="Rank by the spot estimate."),
               limit: int = typer.Option(20, "--limit", help="How many rows to show.")) -> None:
        """Types offered in the region that meet every filter, cheapest first, with their price's date."""
        if ctx.invoked_subcommand is not None:
            return
        if arch not in (None, "x86_64", "arm64"):
            raise typer.BadParameter(f"{arch!r} is not x86_64 or arm64", param_hint="--arch")
        chosen: Arch | None = "arm64" if arch == "arm64" else ("x86_64" if arch else None)
        _searchable(CLOUD.catalogue, region)
        asked = functools.partial(CLOUD.catalogue.search, region=region, gpu=True if gpu == "any" else gpu,
                                  arch=chosen, vcpus=vcpus, memory=memory, spot=spot)
        found = asked()
        unpriced = not found and not any(CLOUD.catalogue.price(t, region) for t in CLOUD.catalogue.types
                                         if CLOUD.catalogue.offered(t, region))
        if unpriced:  # a region with no price source: its types, with their cost shown as unknown
            found = asked(priced_only=False)
        out = table(f"EC2 in {region}: {len(found)} types" + (", prices unknown" if unpriced else ""), "type", "vCPU",
                    "GiB", "arch", "GPU", "$/hour", "spot $/hour", "price as of")
        for offer in found[:limit]:
            out.add_row(*_row(offer))
        console().print(out)
        if unpriced:
            typer.echo(f"The catalogue has no prices for {region}: `fogiac catalog update --region {region}` "
                       "reads them with your credentials.")

    @cat.command("update")
    def update(regions: list[str] = typer.Option(None, "--region", help="Regions to read (default: all known)."),
               out: Path | None = typer.Option(None, "--out", help="Write here instead of the state folder."),
               spot: bool = typer.Option(True, "--spot/--no-spot", help="Read spot price history too.")) -> None:
        """Rebuild the catalogue from DescribeInstanceTypes, the Price List API and spot price history."""
        wanted = list(regions or CLOUD.catalogue.regions)
        for region in wanted:
            if region not in CLOUD.catalogue.regions and region not in known.regions():
                raise _typo(CLOUD.catalogue, region)
        clients: dict[str, Any] = {}

        def ec2_for(region: str) -> Any:
            return clients.setdefault(region, api.client("ec2", region=region))

        built = refresh.from_aws(regions=wanted, ec2_for=ec2_for, spot=spot,
                                 pricing=api.client("pricing", region=refresh.PRICING_REGION))
        read = (len(built.hardware), len(built.on_demand))
        unpriced = [r for r in wanted if not any(region == r for _, region in built.on_demand)]
        current = CLOUD.catalogue
        kept = built.keep(current, refreshed=wanted)  # the regions not read keep their facts and dates
        path = built.write(out or user_catalogue())
        typer.echo(f"{path}: {read[0]} types in {len(wanted)} regions, {read[1]} on-demand prices")
        if kept:
            typer.echo(f"kept {len(kept)} other regions as they were in {current.path} (each price with its source "
                       "and date)")
        for region in unpriced:  # said, never left to read as $0
            typer.echo(f"warning: the Price List answered no on-demand price for {region}: costs there stay unknown",
                       err=True)

    return cat
