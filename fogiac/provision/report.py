"""Render a :class:`~fogiac.provision.runner.ProvisionReport` as a rich table, one row per host."""

from __future__ import annotations

from rich.table import Table

from fogiac.provision.runner import ProvisionReport

_STYLE = {"ok": "green", "changed": "yellow", "failed": "bold red"}


def report_table(report: ProvisionReport, *, title: str = "provisioning") -> Table:
    table = Table(title=f"{title}: {report.summary()} in {report.seconds:.1f}s", title_justify="left")
    for column in ("host", "address", "steps changed", "status", "pushed", "error"):
        table.add_column(column, overflow="fold")
    for host in report.hosts:
        status = "failed" if not host.ok else "changed" if host.changed else "ok"
        table.add_row(
            host.host, host.address, ", ".join(host.changed) or "-", f"[{_STYLE[status]}]{status}[/]",
            f"{host.files_pushed} files, {host.bytes_sent} B", host.error or "",
        )
    return table
