"""``fogiac vpn up|down|status``: the edge's connection to a target's VPN.

The commands are the target's (the aws target's Client VPN: ``fogiac.targets.aws.vpncli``),
found through the plug-in registry (group ``fogiac.commands``), so the CLI imports no target;
this module is here so that ``vpn`` is a verb like the others, loaded only when it runs.
"""

from __future__ import annotations

import typer

from fogiac import plugins

GROUP = "fogiac.commands"


def register(app: typer.Typer) -> None:
    app.add_typer(plugins.load(GROUP, "vpn")(), name="vpn")
