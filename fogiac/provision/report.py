"""Render a :class:`~fogiac.provision.runner.ProvisionReport` as a rich table, one row per host."""

from __future__ import annotations

from rich.markup import escape
from rich.table import Table

from fogiac.plan.review import visible
from fogiac.provision.runner import ProvisionReport

_STYLE = {"ok": "green", "changed": "yellow", "failed": "bold red"}


def report_table(report: ProvisionReport, *, title: str = "provisioning") -> Table:
    table = Table(title=f"{title}: {report.summary()} in {report.seconds:.1f}s", title_justify="left")
    for column in ("host", "address", "steps changed", "status", "pushed", "error"):
        table.add_column(column, overflow="fold")
    for host in report.hosts:
        status = "failed" if not host.ok else "changed" if host.changed else "ok"
        # a host's error quotes what the host said: shown with its controls escaped, never as markup
        table.add_row(
            escape(visible(host.host)), escape(visible(host.address)), escape(visible(", ".join(host.changed) or "-")),
            f"[{_STYLE[status]}]{status}[/]", f"{host.files_pushed} files, {host.bytes_sent} B",
            escape(visible(host.error or "")),
        )
    return table
