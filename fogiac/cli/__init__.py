"""The ``fogiac`` command line: one module per group of verbs, each with ``register(app)``.

Every module in this package that defines ``register`` is picked up, so adding a verb group
never edits this file. Errors a user can act on (:class:`fogiac.errors.FogiacError`) are caught
here once and printed one line each, exit code 1, never a traceback.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys

import typer
from typer.core import TyperGroup

from fogiac.errors import FogiacError, ManifestError


class _FogiacGroup(TyperGroup):
    """Turns a FogiacError from any command into clean output and exit status 1."""

    def invoke(self, ctx):  # type: ignore[no-untyped-def,override]
        try:
            return super().invoke(ctx)
        except ManifestError as err:
            for line in err.problems:
                typer.echo(line, err=True)
            raise typer.Exit(1) from None
        except FogiacError as err:
            typer.echo(f"error: {err}", err=True)
            raise typer.Exit(1) from None

    def list_commands(self, ctx) -> list[str]:  # type: ignore[no-untyped-def]
        return sorted(super().list_commands(ctx))


app = typer.Typer(
    cls=_FogiacGroup,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    help="Deploy parts of a robot's ROS graph to cloud or lab machines from one manifest.",
)


@app.callback()
def _root() -> None:
    """fogiac: plan before apply, undo everything on down."""


def _register_all() -> None:
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(app)


_register_all()


def main() -> None:
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
