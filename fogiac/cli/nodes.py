"""``fogiac provision``, ``fogiac logs NODE`` and ``fogiac ssh NODE``: work on provisioned hosts.

Thin: find the stack from the manifest, call :mod:`fogiac.provision`, render with rich.
``logs`` and ``ssh`` find hosts from what the last provisioning recorded, so they work on every
target (``aws``, ``hosts``, ``local``).
"""

from __future__ import annotations

import os
import selectors
import shlex
import subprocess
import sys
from pathlib import Path
from typing import Any

import typer

from fogiac import targets
from fogiac.certs import load_or_create_bundle
from fogiac.cli._common import ENV, MANIFEST, TARGET, compile_deployed, compile_for
from fogiac.errors import ProvisionError
from fogiac.hostmodel import node_instances
from fogiac.lifecycle.driver import Created, Feature
from fogiac.plan.model import Plan
from fogiac.provision import provision, recorded_access
from fogiac.provision import teardown as tear_down
from fogiac.provision.managers import manager_for
from fogiac.provision.report import report_table
from fogiac.provision.services import Layout
from fogiac.state import StackState, stack_lock
from fogiac.tables import console
from fogiac.termtext import TerminalFilter, clean


def _host_of(node: str, manifest: Path, env: str) -> tuple[str, Any, str, Path, Plan]:
    """(host name, access, base, stack dir, plan) of the host running ``node``, from the last provisioning;
    the target that made the stack reads its recorded access back."""
    plan = compile_deployed(manifest, env)
    known = sorted(instance for n in plan.nodes for instance in node_instances(plan, n))
    if node not in known:
        bare = [n for n in known if n.partition("@")[0] == node]
        if bare:  # a per-robot node runs one instance per robot, each its own service and log
            raise ProvisionError(f"node {node!r} runs one instance per robot: name one ({', '.join(bare)})")
        raise ProvisionError(f"{manifest} has no node {node!r}; its nodes: {', '.join(known)}")
    node = node.partition("@")[0]  # the host records the node, which runs each robot's instance
    chosen = targets.get(plan.target)
    if Feature.PROVISIONS not in chosen.features:
        raise ProvisionError(f"target {plan.target} runs its nodes itself: fogiac reaches none of its hosts, so "
                             f"node {node!r} has no host to open here")
    state = StackState(plan.stack).folder
    for name, (access, base, nodes) in recorded_access(state, chosen.access_from).items():
        if node in nodes:
            return name, access, base, state, plan
    raise ProvisionError(f"node {node!r} is not deployed: stack {plan.stack} is not up; "
                         f"run `fogiac up {manifest}` first")


def _pump(child: subprocess.Popen[bytes]) -> None:
    """Copy the child's stdout and stderr to ours as they come, each through its own terminal filter."""
    assert child.stdout is not None and child.stderr is not None
    ours = {child.stdout.fileno(): (sys.stdout, TerminalFilter()),
            child.stderr.fileno(): (sys.stderr, TerminalFilter())}
    with selectors.DefaultSelector() as selector:
        for fd in ours:
            selector.register(fd, selectors.EVENT_READ)
        while selector.get_map():
            for key, _ in selector.select():
                data = os.read(key.fd, 65536)
                out, screen = ours[key.fd]
                if not data:
                    selector.unregister(key.fd)
                out.write(screen.feed_bytes(data, final=not data))
                out.flush()


def _follow(argv: list[str]) -> None:
    """Run the follow command until it ends or Ctrl-C (which ends it quietly, exit 0); what it prints
    reaches the terminal without escape sequences (a node's output is not the operator's to trust)."""
    child = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        _pump(child)
        code = child.wait()
    except KeyboardInterrupt:
        child.terminate()
        child.wait()
        return
    if code != 0:
        raise typer.Exit(code)


def register(app: typer.Typer) -> None:
    @app.command("provision")
    def provision_cmd(manifest: Path = MANIFEST, target: str | None = TARGET, env: str = ENV,
                      health_timeout: float = typer.Option(30.0, help="Seconds to wait for each node."),
                      allow_install: bool = typer.Option(False, help="Install ROS from OS packages if missing."),
                      teardown: bool = typer.Option(False, "--teardown", help="Stop everything and remove it.")
                      ) -> None:
        """Provision an existing set of hosts (no cloud resources): ROS, code, nodes, relay."""
        plan = compile_for(manifest, env, target)
        chosen = targets.get(plan.target)
        if Feature.PROVISIONS not in chosen.features:
            raise ProvisionError(f"target {plan.target} runs its nodes itself: `fogiac provision` has nothing to "
                                 "provision there; `fogiac up` starts them")
        if Feature.CREATES_MACHINES in chosen.features:
            usable = ", ".join(n for n in targets.names() if Feature.CREATES_MACHINES not in targets.get(n).features
                               and Feature.PROVISIONS in targets.get(n).features)
            raise ProvisionError(f"`fogiac provision` is for targets whose machines exist ({usable}); "
                                 f"{plan.target} hosts are provisioned by `fogiac up`")
        stack = StackState(plan.stack)
        state = stack.ensure()
        screen = console()
        with stack_lock(plan.stack, operation="teardown" if teardown else "provision"):
            reach = chosen.reach(plan, Created(plan=plan), announce=lambda line: None)
            if teardown:
                report = tear_down(plan, hosts=reach.access, state_dir=state)
            else:
                load_or_create_bundle(plan.stack, stack.certs)
                with screen.status(f"provisioning {len(plan.hosts)} host(s)"):
                    report = provision(plan, hosts=reach.access, state_dir=state, certs_dir=stack.certs,
                                       health_timeout=health_timeout, allow_install=allow_install, ports=reach.ports)
        screen.print(report_table(report, title="teardown" if teardown else "provisioning"))
        for failed in report.failed:  # whole lines, whatever the terminal's width
            typer.echo(f"error: {failed.error}", err=True)
        typer.echo(report.summary())
        if not report.ok:
            raise typer.Exit(1)

    @app.command("logs")
    def logs(node: str, manifest: Path = MANIFEST, env: str = ENV,
             lines: int = typer.Option(100, "--lines", "-n", help="How many lines."),
             follow: bool = typer.Option(False, "--follow", "-f",
                                         help="Keep printing what the node writes until Ctrl-C.")) -> None:
        """Print the last lines a node wrote on its host (--follow: and what it writes next), as plain text: a
        node's escape sequences never reach your terminal."""
        name, access, base, state, plan = _host_of(node, manifest, env)
        host = access.open(name=name, known_hosts=StackState.at(state).known_hosts, stack=plan.stack)
        try:
            host.connect()
            command = manager_for(host).logs_command(Layout(base or host.base, plan.stack), f"node-{node}", lines=lines,
                                                     follow=follow)
            if follow:  # streamed by a process of its own: the host's run() returns only when a command ends
                host.close()
                _follow(access.follow_argv(command, known_hosts=StackState(plan.stack).known_hosts))
                return
            text = clean(host.run(command, check=False).stdout)
            typer.echo(text, nl=False)
            if not text.strip():  # a node still loading has nothing to show yet; say so rather than print nothing
                typer.echo(f"(node {node} on {name} has written nothing yet)", err=True)
        finally:
            host.close()

    @app.command("ssh")
    def ssh(node: str, manifest: Path = MANIFEST, env: str = ENV,
            print_only: bool = typer.Option(False, "--print", help="Print the command instead of running it.")) -> None:
        """Open a shell on the host running NODE (a local sandbox: a shell in its folder)."""
        name, access, base, state, plan = _host_of(node, manifest, env)
        argv, cwd = access.shell_argv(base=base, known_hosts=StackState(plan.stack).known_hosts)
        if print_only:
            typer.echo(f"(cd {shlex.quote(cwd)} && {shlex.join(argv)})" if cwd != os.getcwd() else shlex.join(argv))
            return
        os.chdir(cwd)
        os.execvp(argv[0], argv)
