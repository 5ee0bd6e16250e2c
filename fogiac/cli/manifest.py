"""Verbs about the manifest itself: ``validate`` and ``schema``. No cloud SDK is imported."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from fogiac.cli._common import MANIFEST, TARGET, load
from fogiac.errors import FogiacError
from fogiac.manifest.clouds import prices as price_source
from fogiac.manifest.crossing import unlisted
from fogiac.manifest.schema import json_schema, parse_manifest
from fogiac.net import middleware
from fogiac.plan import placeholders
from fogiac.plan.compile import compile_plan
from fogiac.plan.cost import MONTH, per_month, saving_pct, total_words, unknown_note
from fogiac.state import write_text_atomic
from fogiac.tables import console, table


def validate(
    manifest: Path = MANIFEST,
    target: str | None = TARGET,
) -> None:
    """Check a manifest; print every problem as FILE:LINE: field: what is wrong."""
    loaded = load(manifest)
    plan = compile_plan(loaded, target=target)
    typer.echo(
        f"{manifest}: valid ({len(loaded.nodes)} node{'s' if len(loaded.nodes) != 1 else ''}, "
        f"{len(plan.hosts)} host{'s' if len(plan.hosts) != 1 else ''}, target {plan.target})"
    )
    for line in placeholders.found(plan):  # valid, but copied from the documentation: `up` refuses it
        typer.echo(f"warning: {line}", err=True)
    for line in unlisted(loaded):  # valid, but nothing crosses (an imported FogROS2 node's empty lists)
        typer.echo(f"warning: {line}", err=True)


def schema() -> None:
    """Print the manifest's JSON Schema, for editors to complete and check fogiac.yaml."""
    typer.echo(json.dumps(json_schema(), indent=2, sort_keys=True))




def init(
    path: Path = typer.Argument(Path("fogiac.yaml"), help="Where to write the starter manifest."),
    name: str = typer.Option("my-robot", "--name", help="Deployment name (DNS-safe)."),
) -> None:
    """Write a starter manifest (never over an existing one)."""
    if path.exists():
        raise FogiacError(f"{path} exists; edit it, or pick another path")
    from fogiac.render import render  # noqa: PLC0415 - jinja2 only for init, never for validate (test_startup)

    text = render("manifest/starter.yaml.j2", name=name)
    parse_manifest(text, source=str(path))
    write_text_atomic(path, text)
    typer.echo(f"wrote {path}; next: fogiac validate {path} && fogiac plan {path}")


def cost(manifest: Path = MANIFEST, target: str | None = TARGET) -> None:
    """What the deployment costs per hour, day and month (730 h, as AWS counts), line by line: on-demand
    prices, and for spot hosts the catalogue's spot estimate beside them."""
    plan = compile_plan(load(manifest), target=target)
    spot = plan.spot_hourly_usd
    extra = ("spot $/hour", f"spot $/{MONTH}") if spot is not None else ()
    out = table(f"{plan.stack} (--env {plan.environment}; {plan.target}, {plan.region})",
                "item", "$/hour", "$/day", f"$/{MONTH}", *extra)
    for column in out.columns[1:]:
        column.justify = "right"
    for line in plan.cost:
        known = line.known or line.spot_usd_per_hour is not None
        beside = _spot(line.spot_total if known else None) if spot is not None else ()
        out.add_row(line.item, *_amounts(line.total if line.known else None), *beside)
    total = plan.hourly_usd
    unknown = plan.unknown_costs
    beside = _spot(spot, len(unknown)) if spot is not None else ()
    out.add_row("total", *_amounts(total, len(unknown)), *beside, style="bold")
    screen = console()
    screen.print(out)
    if unknown:  # a sum that leaves these out is at least that much, never the whole cost
        screen.print(f"cost: {total_words(total, len(unknown))}", markup=False)
        screen.print(f"  {unknown_note(unknown)}", markup=False)
    carrier = middleware.get(plan.middleware)
    screen.print(f"ROS {plan.ros_distro} via {carrier.label}; edge: {carrier.edge_side}; "
                 f"each host: {carrier.cloud_side} (no charge beyond the hosts)", markup=False)
    prices = price_source(plan.target)
    screen.print(f"prices: {prices.source} ({prices.as_of})", markup=False, style="dim")
    if spot is not None:
        at = f"at least ${spot:.4f} per hour plus {len(unknown)} unknown" if unknown else f"${spot:.4f} per hour"
        screen.print(f"with spot: {at}, {saving_pct(plan.hourly_usd, spot)}% less than on-demand "
                     f"(an estimate; {prices.spot_ceiling})", markup=False)
        screen.print(f"spot prices: {prices.spot_source} ({prices.spot_as_of}); {prices.spot_method}",
                     markup=False, style="dim")


def _amounts(usd_per_hour: float | None, unknown: int = 0) -> tuple[str, str, str]:
    """The hour, the day and the month (730 h) as the table shows them: ``unknown`` where the price is
    (never ``0.0000``), and ``+ N unknown`` after a total that leaves N lines out."""
    if usd_per_hour is None:
        return ("unknown",) * 3
    plus = f" + {unknown} unknown" if unknown else ""
    return (f"{usd_per_hour:.4f}{plus}", f"{usd_per_hour * 24:.2f}{plus}", f"{per_month(usd_per_hour):.2f}{plus}")


def _spot(usd_per_hour: float | None, unknown: int = 0) -> tuple[str, str]:
    hour, _, month = _amounts(usd_per_hour, unknown)
    return hour, month


def register(app: typer.Typer) -> None:
    app.command()(init)
    app.command()(validate)
    app.command()(schema)
    app.command()(cost)
