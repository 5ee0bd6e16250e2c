"""The ``fogiac`` command line: one module per group of verbs, each with ``register(app)``.

A verb's module is imported only when that verb runs (each verb is an entry point of the
``fogiac.commands`` group naming its module, the way click's lazily loaded groups work), so
``fogiac validate`` does not pay for the relay, the VPN or the provisioning code, and another
installed package can add a group of verbs; ``tests/cli/test_verbs.py`` keeps the entry points
equal to what the modules register. Errors a user can act on (:class:`fogiac.errors.FogiacError`) are caught
here once and printed one line each, exit code 1, never a traceback.
"""

from __future__ import annotations

import importlib
import sys
import warnings
from typing import Any, TextIO

import typer
from typer.core import TyperGroup

from fogiac import __version__
from fogiac.errors import FogiacError, ManifestError
from fogiac.registry import Registry

# typer builds on click, and newer typers carry their own copy of it (``typer._click``), whose classes
# are not the ``click`` package's: a click installed beside it (mkdocs brings one) must not be the type
# checked against. Contexts, commands and parameters are typed loosely here for that reason.
Context = Any
Command = Any
Parameter = Any


def _flags_without_type(params: list[Parameter]) -> list[Parameter]:
    """Rich help in typer >= 0.2x prints a type (``<bool>``) beside every option, flags included.

    A flag takes no value, so it has no type to show: typer prints an option's metavar instead
    of its type when one is set, and an empty one prints nothing.
    """
    for param in params:
        if getattr(param, "is_flag", False):
            param.metavar = ""
    return params


def _with_subcommands(command: Command | None) -> list[Command]:
    if command is None:
        return []
    return [command, *(c for sub in getattr(command, "commands", {}).values() for c in _with_subcommands(sub))]


# ``fogiac --help`` lists the everyday workflow first, in the order it runs, as Terraform's does;
# every other verb (and any a plug-in adds) follows in the second panel, alphabetically.
MAIN_PANEL = "Main commands"
OTHER_PANEL = "Other commands"
MAIN_COMMANDS = ("init", "validate", "plan", "up", "status", "down")

# Other tools' verbs for what fogiac calls otherwise: answered with the one to use, exit 2 (a usage error).
SYNONYMS = {"apply": "up", "destroy": "down", "preview": "plan"}


class _FogiacGroup(TyperGroup):
    """Turns a FogiacError from any command into clean output and exit status 1."""

    def get_params(self, ctx: Context) -> list[Parameter]:
        return _flags_without_type(super().get_params(ctx))

    def invoke(self, ctx: Context) -> Any:
        try:
            return super().invoke(ctx)
        except ManifestError as err:
            for line in err.problems:
                typer.echo(line, err=True)
            raise typer.Exit(1) from None
        except FogiacError as err:
            typer.echo(f"error: {err}", err=True)
            raise typer.Exit(1) from None

    def list_commands(self, ctx: Context) -> list[str]:
        names = COMMANDS.names()
        return [*(n for n in MAIN_COMMANDS if n in names), *(n for n in names if n not in MAIN_COMMANDS)]

    def get_command(self, ctx: Context, cmd_name: str) -> Command | None:
        if cmd_name not in COMMANDS.names():
            return None
        command = verbs_of(COMMANDS.value(cmd_name)).get(cmd_name)
        for each in _with_subcommands(command):
            _flags_without_type(each.get_params(ctx))
        if command is not None:
            command.rich_help_panel = MAIN_PANEL if cmd_name in MAIN_COMMANDS else OTHER_PANEL
        return command

    def resolve_command(self, ctx: Any, args: list[str]) -> Any:
        """``fogiac apply`` and its kind: one line naming fogiac's verb, exit 2, as click's usage errors."""
        verb = args[0] if args else ""
        if verb in SYNONYMS and verb not in COMMANDS.names():
            typer.echo(f"error: fogiac has no `{verb}`; did you mean `fogiac {SYNONYMS[verb]}`?", err=True)
            ctx.exit(2)
        return super().resolve_command(ctx, args)


COMMANDS: Registry[object] = Registry("fogiac.commands", what="command")  # verb -> the module registering it


def verbs_of(module: str) -> dict[str, Command]:
    """The click commands the module ``module`` registers, by name (imports the module)."""
    group = typer.Typer(context_settings={"help_option_names": ["-h", "--help"]})
    importlib.import_module(module).register(group)

    @group.callback()
    def _group() -> None:
        pass

    built = typer.main.get_command(group)
    return dict(built.commands) if isinstance(built, TyperGroup) else {}


app = typer.Typer(
    cls=_FogiacGroup,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    help="Deploy parts of a robot's ROS graph to cloud or lab machines from one manifest.",
    context_settings={"help_option_names": ["-h", "--help"]},
)


def _version(shown: bool) -> None:
    if shown:
        typer.echo(f"fogiac {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="Print fogiac's version and exit.")) -> None:
    """fogiac: plan before apply, undo everything on down."""


_SHOW = warnings.showwarning


# A note about how the manifest reads (a replicated node's reply match that no stated type checks) is the
# reviewing commands' to say; `down`, `status`, `logs` and the rest compile the same manifest but keep quiet.
_REVIEWING = frozenset({"validate", "plan", "up"})
_MANIFEST_NOTES = frozenset({"MatchUnchecked"})  # by name: the manifest's modules stay unimported at startup


def _command() -> str | None:
    return next((arg for arg in sys.argv[1:] if not arg.startswith("-")), None)


def _one_line(message: Warning | str, category: type[Warning], filename: str, lineno: int,
              file: TextIO | None = None, line: str | None = None) -> None:
    """A warning a user can act on (a cost the catalogue does not know) in one line, like an error."""
    if category.__name__ in _MANIFEST_NOTES and _command() not in _REVIEWING:
        return
    if issubclass(category, UserWarning):
        print(f"warning: {message}", file=sys.stderr)
    else:
        _SHOW(message, category, filename, lineno, file, line)


def main() -> None:
    warnings.showwarning = _one_line
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
