"""``fogiac plan``: what a manifest would change and cost, offline (no credentials, no Pulumi CLI).

Resources print the way ``terraform plan`` reads in a CI log: one line each
(``+ aws:ec2/vpc:Vpc motion-dev-vpc``) with its key inputs indented below; every value whole.
Against what was applied (or, with ``--against``, another version of the manifest) only what
changes is shown, per resource and input, ending in Terraform's ``Plan: ...`` line; against what
was applied, also what the last ``fogiac refresh`` found changed outside fogiac (drift).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import typer
from rich.markup import escape

from fogiac import deployment, registry, targets
from fogiac.cli._common import ENV, MANIFEST, TARGET, compile_deployed, compile_for
from fogiac.errors import FogiacError, StateError
from fogiac.manifest import clouds
from fogiac.manifest.clouds import prices as price_source
from fogiac.manifest.revision import load_revision
from fogiac.plan import drift, placeholders, review, saved
from fogiac.plan.compile import compile_plan
from fogiac.plan.cost import MONTH, budget_words, menu_line, per_month, rate, saving_pct, total_words, unknown_note
from fogiac.plan.diff import annotate, autostop_words, diff_documents, with_drift
from fogiac.plan.document import document, plan_document
from fogiac.plan.guard import ACCEPT_UNKNOWN
from fogiac.state import write_json_atomic
from fogiac.tables import console, table

KEY_INPUTS = "fogiac.key_inputs"  # plug-in group: a Pulumi package -> {resource type: the inputs worth a glance}


def _short(value: Any) -> str:
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}={_short(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(_short(v) for v in value) + "]"
    return str(value)


def _key_inputs(resource: Mapping[str, Any]) -> list[str]:
    """The inputs the table shows, as the resource's package lists them (the JSON has all of them)."""
    inputs, package = resource["inputs"], resource["type"].partition(":")[0]
    listed: Mapping[str, tuple[str, ...]] = registry.find(KEY_INPUTS, package) or {}
    return [f"{k}: {_short(inputs[k])}" for k in listed.get(resource["type"], ()) if k in inputs]


def _render_diff(doc: dict[str, Any], lines: list[str]) -> None:
    out = console()
    stack, target = (escape(review.visible(text)) for text in (stack_label(doc), str(doc["target"])))
    out.print(f"[bold]fogiac plan[/] {stack}: target {target}")
    for line in lines:
        out.print(escape(line), highlight=False)


def _before(compiled: Any, *, against: str | None, target: str | None, env: str) -> tuple[dict[str, Any] | None, str]:
    """The document to compare with, and what it is: another manifest, the applied plan, or none."""
    if against is not None:
        base = load_revision(against)
        plan = compile_plan(base.manifest, target=target, environment=env)
        return document(plan, targets.get(plan.target).declare(plan), manifest_path=against,
                        manifest_sha256=base.sha256), against
    applied = deployment.read_applied(compiled.stack)
    return (applied, f"what was applied to {compiled.stack}") if applied is not None else (None, "nothing")


def _spot_cell(host: Mapping[str, Any]) -> str:
    if not host["spot"]:
        return "no"
    each = host.get("spot_usd_per_hour")
    if each is None:
        return "yes (price unknown)"
    if host["usd_per_hour"] is None:
        return f"{each:.4f}"
    return f"{each:.4f} ({saving_pct(host['usd_per_hour'], each)}% less)"


def stack_label(doc: Mapping[str, Any]) -> str:
    """``first-day-dev (--env dev)``: the stack's name says where its suffix comes from."""
    env = doc.get("environment")
    return f"{doc['stack']} (--env {env})" if env else str(doc["stack"])


def _variant_says(target: str, name: str) -> str | None:
    """An optional word of the target's ``cloud:`` variant for the plan (a sandbox's note, its ports)."""
    said = getattr(clouds.variant(target), name, None) if clouds.known(target) else None
    return said if isinstance(said, str) else None


def _serve_cells(node: Mapping[str, Any]) -> tuple[str, ...]:
    """A fleet node's serves / instances / share cells: ``all (3)``, ``arm1, arm3``, ``per robot (3)``; the share
    is what each robot it serves bears of its part of its host's hour (:mod:`fogiac.plan.fleet`)."""
    serves = node.get("serves") or []
    said = {"all": f"all ({len(serves)})", "per_robot": f"per robot ({len(serves)})"}.get(str(node.get("serve")))
    instances = node.get("instances", 1)
    where = "shared" if instances == 1 else "one per robot"
    return (escape(said or ", ".join(serves)), f"{instances} ({where})", rate(node.get("usd_per_hour_per_robot")))


def _robots_table(robots: list[Mapping[str, Any]]) -> Any:
    """One row per robot: its ROS master, certificate, the nodes it uses, its access and its share of the hour."""
    shown = table(f"robots ({len(robots)}; each its own certificate, namespace and access)", "robot", "ROS master",
                  "certificate", "nodes", "may cross", "hosts' $/h share")
    for r in robots:
        shown.add_row(escape(r["name"]), escape(str(r["entry"])), escape(str(r["certificate"])),
                      escape(", ".join(r["nodes"]) or "-"), escape(", ".join(r["access"])), rate(r["usd_per_hour"]))
    return shown


def render(doc: Mapping[str, Any]) -> None:
    doc = review.visible_doc(doc)  # no value reaches the terminal with a control or bidi character in it
    out = console()
    where = f", region {doc['region']}, mode {doc['mode']}" if doc["resources"] else ""
    out.print(f"[bold]fogiac plan[/] {stack_label(doc)}: target {doc['target']}{where}")
    carrier = doc["middleware"]
    port = _variant_says(doc["target"], "host_ports") or f"port {carrier['port']}"
    out.print(f"ROS {carrier['ros_distro']} via {escape(carrier['label'])}\n  edge: {escape(carrier['edge'])}\n"
              f"  each host: {escape(carrier['cloud'])}, {port}", highlight=False)
    if not doc["resources"]:
        out.print(f"no cloud resources (target {doc['target']})")
    note = _variant_says(doc["target"], "plan_note")
    if note:
        out.print(note, highlight=False)
    for stack in doc["stacks"]:
        rows = [r for r in doc["resources"] if r["stack"] == stack]
        out.print(f"\n[bold]{stack} stack: {len(rows)} to create[/]")
        for r in rows:
            out.print(f"  [green]+[/] {escape(r['type'])} {escape(r['name'])}", highlight=False)
            for line in _key_inputs(r):
                out.print(f"      {escape(line)}", highlight=False)
    out.print()
    hosts = table("hosts", "host", "machine", "address", "vCPUs", "GPUs", "memory GiB", "disk GB", "on-demand $/h",
                  "spot $/h", "nodes")
    machine, size = _variant_says(doc["target"], "host_machine"), _variant_says(doc["target"], "host_size")
    for h in doc["hosts"]:  # a target that rents nothing says where a host runs, and that its size is not its own
        sizes = (size,) * 4 if size else (str(h["vcpus"]), str(h["gpus"]), f"{h['memory_gib']:g}", str(h["disk_gb"]))
        hosts.add_row(h["name"], escape(machine.format(machine=h["machine"])) if machine else h["machine"],
                      escape(str(h["address"] or "-")), *sizes, rate(h["usd_per_hour"]), _spot_cell(h),
                      ", ".join(h["nodes"]) + "".join(f" ({h[k]})" for k in ("replica", "zone") if h.get(k)))
    out.print(hosts)
    for h in doc["hosts"]:
        if h["chosen_for"]:
            out.print(escape(menu_line(h, spot_as_of=price_source(doc["target"]).spot_as_of)), highlight=False)
    robots = doc.get("robots")  # a fleet: whom each node serves, and what each robot brings and costs
    nodes = table("nodes", "node", "host", "kind", "runs", "GPU",
                  *(("serves", "instances", "$/h per robot") if robots is not None else ()))
    for n in doc["nodes"]:
        nodes.add_row(n["name"], ", ".join(n.get("replica_hosts") or [n["host"]]), n["kind"], escape(n["runs"]),
                      "yes" if n["gpu"] else "no", *(_serve_cells(n) if robots is not None else ()))
    out.print(nodes)
    if robots is not None:
        out.print(_robots_table(robots))
    for note in doc.get("notes", ()):  # where placement put replicas, and what it skipped
        out.print(f"note: {escape(note)}", highlight=False)
    spot = doc["cost"].get("spot_hourly_usd")
    columns = ("item", "quantity", "$/h each", "$/h") + (("spot $/h",) if spot is not None else ())
    cost = table("hourly cost (on-demand prices" + ("; spot estimate beside)" if spot is not None else ")"), *columns)
    for line in doc["cost"]["lines"]:
        each = line.get("spot_usd_per_hour")
        every = line["usd_per_hour"] if each is None else each
        cost.add_row(escape(line["item"]), f"{line['quantity']:g}", rate(line["usd_per_hour"]),
                     rate(line["total"]),
                     *((rate(None if every is None else line["quantity"] * every),) if spot is not None else ()))
    total = doc["cost"]["hourly_usd"]
    unknown = len(doc["cost"].get("unknown") or ())
    plus = f" + {unknown} unknown" if unknown else ""
    beside = (f"[bold]{spot:.4f}{plus}[/]",) if spot is not None else ()
    cost.add_row("[bold]total[/]", "", "", f"[bold]{total:.4f}{plus}[/]", *beside)
    out.print(cost)
    out.print(f"cost: {total_words(total, unknown)}", highlight=False)
    if unknown:
        out.print(f"  {escape(unknown_note(doc['cost']['unknown']))}", highlight=False)
    out.print(f"  {escape(autostop_words(doc.get('autostop')))}", highlight=False)  # what bounds that month
    if (budget := budget_words(doc["cost"], accept=f"`fogiac up {ACCEPT_UNKNOWN}`")) is not None:
        out.print(f"  {budget}", highlight=False)
    if spot is not None:
        source = doc["cost"]["spot_prices"]
        out.print(f"with spot: about ${spot:.4f} per hour (${per_month(spot):.2f} per {MONTH}), "
                  f"{saving_pct(total, spot)}% less; spot estimates from {escape(source['source'].split(' (')[0])} "
                  f"({source['as_of']}), never more than on-demand", highlight=False)
    summary = doc.get("changes", {}).get("summary")
    if summary:
        out.print(f"\n{summary}")


def plan(
    manifest: Path = MANIFEST,
    target: str | None = TARGET,
    env: str = ENV,
    as_json: bool = typer.Option(False, "--json", help="Print the versioned JSON document."),
    out: Path | None = typer.Option(None, "--out", help="Also save the JSON document to this file (-: print it)."),
    detailed_exitcode: bool = typer.Option(
        False, "--detailed-exitcode", help="Exit 0 when the diff is empty, 2 when something would change."
    ),
    against: str | None = typer.Option(
        None, "--against", metavar="BASE",
        help="Compare with another version of the manifest (a path, or git:REF:PATH) instead of what was applied.",
    ),
    markdown: bool = typer.Option(False, "--markdown", help="Print the diff as a pull-request comment."),
    fmt: str | None = typer.Option(
        None, "--format", metavar="FORMAT",
        help="terraform-json: the plan as Terraform plan JSON, for policy scanners (checkov, Trivy, conftest).",
    ),
) -> None:
    """Show what the manifest would create, change or destroy, and what it costs, without touching the cloud."""
    # Compared with what is deployed, the plan is for the target the deployment went to.
    compiled = compile_deployed(manifest, env, target) if detailed_exitcode and against is None \
        else compile_for(manifest, env, target)
    for line in placeholders.found(compiled):  # on stderr: stdout stays the document or the comment
        typer.echo(f"warning: {line}; `fogiac up` refuses it without --force", err=True)
    declared = plan_document(compiled, targets.get(compiled.target).declare(compiled), manifest=manifest)
    before, label = _before(compiled, against=against, target=target, env=env)
    try:  # everything read from the applied document, before a line is printed
        diff = diff_documents(before, declared, against="manifest" if against else "applied")
        refreshed = drift.load(compiled.stack) if against is None and before is not None else None
        if refreshed is not None:  # what `fogiac refresh` found changed outside fogiac since the apply
            diff = with_drift(diff, refreshed.drift, refreshed_at=refreshed.at)
        doc = annotate(declared, diff)
        comment = review.comment(diff, stack=compiled.stack, against=label, doc=doc,
                                 placeholders=tuple(placeholders.found(compiled))) if markdown else ""
        lines = review.terminal(diff, against=label) if before is not None else []
    except (TypeError, KeyError, AttributeError, ValueError) as err:
        if against is not None or before is None:
            raise
        # a value fogiac never writes (a number where a name goes, a host row without its name): one line
        raise StateError(f"{deployment.applied_where(compiled.stack)}: not a plan document fogiac applied "
                         f"({type(err).__name__}: {err}); the next `fogiac up` writes it again, or remove it") from None
    if out is not None:  # a saved plan binds what up must find unchanged to apply it (fogiac.plan.saved)
        doc = saved.bind(doc, plan=compiled)
    if out is not None and str(out) == "-":  # the document on stdout, instead of the table
        as_json = True
    elif out is not None:
        _save(out, doc)
    if fmt is not None:  # the target writes its own formats; the CLI only prints
        typer.echo(json.dumps(targets.exporter(compiled.target, fmt)(doc), indent=2, sort_keys=True))
    elif as_json:
        typer.echo(json.dumps(doc, indent=2, sort_keys=True))
    elif markdown:
        typer.echo(comment, nl=False)
    elif before is None:
        render(doc)
    else:
        _render_diff(doc, lines)
    if detailed_exitcode:
        raise typer.Exit(0 if diff.empty else 2)


def _save(out: Path, doc: Mapping[str, Any]) -> None:
    """``--out FILE``: a regular file, replaced whole. A link, device or FIFO is refused: replacing it would
    turn ``/dev/null`` into a file or write through a link somewhere else."""
    if out.is_symlink() or (out.exists() and not out.is_file()):
        kind = "a symbolic link" if out.is_symlink() else "a directory" if out.is_dir() else "not a regular file"
        raise FogiacError(f"--out {out}: is {kind}; name a regular file to write (or - for stdout)")
    try:
        write_json_atomic(out, doc, mode=0o644)
    except OSError as err:
        raise FogiacError(f"--out {out}: cannot write: {err.strerror or err}") from None


def register(app: typer.Typer) -> None:
    app.command()(plan)
