"""``fogiac plan``: what a manifest would create and cost, offline (no credentials, no Pulumi CLI).

Resources print the way ``terraform plan`` reads in a CI log: one line each
(``+ aws:ec2/vpc:Vpc motion-dev-vpc``) with its key inputs indented below; every value whole.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import typer
from rich.markup import escape

from fogiac import targets
from fogiac.cli._common import ENV, MANIFEST, TARGET, compile_for
from fogiac.errors import FogiacError
from fogiac.plan.document import APPLIED_FILE, plan_document
from fogiac.state import read_json, stack_dir, write_json_atomic
from fogiac.tables import console, table

_RULE = ("ipProtocol", "fromPort", "toPort", "cidrIpv4", "cidrIpv6")
# The inputs worth a glance in the table, per resource type (the JSON has all of them).
KEY_INPUTS: dict[str, tuple[str, ...]] = {
    "aws:ec2/vpc:Vpc": ("cidrBlock",),
    "aws:ec2/subnet:Subnet": ("cidrBlock", "availabilityZone", "mapPublicIpOnLaunch"),
    "aws:ec2/routeTable:RouteTable": ("routes",),
    "aws:ec2/routeTableAssociation:RouteTableAssociation": ("subnetId", "routeTableId"),
    "aws:ec2/securityGroup:SecurityGroup": ("name",),
    "aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule": _RULE,
    "aws:vpc/securityGroupEgressRule:SecurityGroupEgressRule": _RULE,
    "aws:acm/certificate:Certificate": ("certificateBody", "privateKey"),
    "aws:ec2clientvpn/endpoint:Endpoint": ("clientCidrBlock", "splitTunnel", "transportProtocol", "vpnPort",
                                           "authenticationOptions"),
    "aws:ec2clientvpn/networkAssociation:NetworkAssociation": ("subnetId",),
    "aws:ec2clientvpn/authorizationRule:AuthorizationRule": ("targetNetworkCidr",),
    "aws:ec2/keyPair:KeyPair": ("keyName",),
    "aws:ec2/instance:Instance": ("instanceType", "ami", "rootBlockDevice", "metadataOptions", "instanceMarketOptions"),
}


def _short(value: Any) -> str:
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}={_short(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(_short(v) for v in value) + "]"
    return str(value)


def _key_inputs(resource: dict[str, Any]) -> list[str]:
    inputs = resource["inputs"]
    return [f"{k}: {_short(inputs[k])}" for k in KEY_INPUTS.get(resource["type"], ()) if k in inputs]


def _render(doc: dict[str, Any]) -> None:
    out = console()
    where = f", region {doc['region']}, mode {doc['mode']}" if doc["resources"] else ""
    out.print(f"[bold]fogiac plan[/] {doc['stack']}: target {doc['target']}{where}")
    if not doc["resources"]:
        out.print(f"no cloud resources (target {doc['target']})")
    for stack in doc["stacks"]:
        rows = [r for r in doc["resources"] if r["stack"] == stack]
        out.print(f"\n[bold]{stack} stack: {len(rows)} to create[/]")
        for r in rows:
            out.print(f"  [green]+[/] {escape(r['type'])} {escape(r['name'])}", highlight=False)
            for line in _key_inputs(r):
                out.print(f"      {escape(line)}", highlight=False)
    out.print()
    hosts = table("hosts", "host", "machine", "address", "vCPUs", "GPUs", "memory GiB", "disk GB", "spot", "$/h",
                  "nodes")
    for h in doc["hosts"]:
        hosts.add_row(h["name"], h["machine"], escape(str(h["address"] or "-")), str(h["vcpus"]), str(h["gpus"]),
                      f"{h['memory_gib']:g}", str(h["disk_gb"]), "yes" if h["spot"] else "no",
                      f"{h['usd_per_hour']:.4f}", ", ".join(h["nodes"]))
    out.print(hosts)
    nodes = table("nodes", "node", "host", "kind", "runs", "GPU")
    for n in doc["nodes"]:
        nodes.add_row(n["name"], n["host"], n["kind"], escape(n["runs"]), "yes" if n["gpu"] else "no")
    out.print(nodes)
    cost = table("hourly cost (on-demand prices; spot at most this)", "item", "quantity", "$/h each", "$/h")
    for line in doc["cost"]["lines"]:
        cost.add_row(escape(line["item"]), f"{line['quantity']:g}", f"{line['usd_per_hour']:.4f}",
                     f"{line['total']:.4f}")
    total = doc["cost"]["hourly_usd"]
    cost.add_row("[bold]total[/]", "", "", f"[bold]{total:.4f}[/]")
    out.print(cost)
    out.print(f"cost: ${total:.4f} per hour (about ${total * 730:.2f} per month if left running)")


def plan(
    manifest: Path = MANIFEST,
    target: str | None = TARGET,
    env: str = ENV,
    as_json: bool = typer.Option(False, "--json", help="Print the versioned JSON document."),
    out: Path | None = typer.Option(None, "--out", help="Also save the JSON document to this file."),
    detailed_exitcode: bool = typer.Option(
        False, "--detailed-exitcode", help="Exit 0 when nothing would change since the last up, 2 when something would."
    ),
) -> None:
    """Show every resource, host and hourly cost the manifest implies, without touching the cloud."""
    compiled = compile_for(manifest, env, target)
    doc = plan_document(compiled, targets.get(compiled.target).declare(compiled), manifest=manifest)
    if out is not None:
        if out.is_dir():
            raise FogiacError(f"--out {out}: is a directory; name the file to write")
        try:
            write_json_atomic(out, doc, mode=0o644)
        except OSError as err:
            raise FogiacError(f"--out {out}: cannot write: {err.strerror or err}") from None
    if as_json:
        typer.echo(json.dumps(doc, indent=2, sort_keys=True))
    else:
        _render(doc)
    if detailed_exitcode:
        applied = read_json(stack_dir(compiled.stack, create=False) / APPLIED_FILE)
        unchanged = isinstance(applied, dict) and applied.get("plan_digest") == doc["plan_digest"]
        raise typer.Exit(0 if unchanged else 2)


def register(app: typer.Typer) -> None:
    app.command()(plan)
