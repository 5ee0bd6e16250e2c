"""Secrets a manifest names (``env: {API_TOKEN: {secret: env:NAME}}``): read at ``up`` on the operator's
machine and written only on the host, in a 0600 file the node's service reads.

The plan, the recorded state and every comment hold the reference (``env:NAME``, ``file:PATH``), never
the value: this module is the one place a value is read, and it hands it only to the file written on
the host. :func:`problems` runs before ``up`` creates anything, so a missing secret stops it whole.
"""

from __future__ import annotations

import os
import stat
import warnings
from pathlib import Path

from fogiac.errors import ProvisionError
from fogiac.plan.model import NodeSpec, Plan

MAX_BYTES = 64 * 1024  # a token or a password, not a file of its own


class SecretExposed(UserWarning):
    """A ``file:`` secret others on this machine can read: used, and said in one line, as ssh says of a key
    (once per file and run: the warning is raised at one place, so Python shows each message once)."""


def _exposed(ref: str, path: Path) -> None:
    """Warn when ``path`` grants group or other users any access (ssh's test for a private key file)."""
    mode = stat.S_IMODE(path.stat().st_mode)
    if mode & 0o077:
        warnings.warn(SecretExposed(f"secret {ref}: other users can read it (mode {mode:04o}); "
                                    f"keep it to yourself: chmod 600 {path}"), stacklevel=2)


def read(ref: str) -> str:
    """The value ``ref`` names; ProvisionError (one line, no value) when it is not there."""
    kind, _, name = ref.partition(":")
    if kind == "env":
        value = os.environ.get(name)
        if value is None:
            raise ProvisionError(f"secret {ref}: {name} is not set in the environment `fogiac up` runs in")
    elif kind == "file":
        path = Path(name)
        try:
            if not path.is_file():
                raise ProvisionError(f"secret {ref}: not a regular file")
            if path.stat().st_size > MAX_BYTES:
                raise ProvisionError(f"secret {ref}: larger than {MAX_BYTES} bytes")
            _exposed(ref, path)
            value = path.read_text()
        except (OSError, UnicodeDecodeError) as err:
            raise ProvisionError(f"secret {ref}: cannot be read ({getattr(err, 'strerror', None) or err})") from None
        value = value[:-1] if value.endswith("\n") else value  # `echo token > file` holds one line
        value = value[:-1] if value.endswith("\r") else value
    else:
        raise ProvisionError(f"secret {ref}: not env:NAME or file:PATH")
    if not value.replace("\t", "").isprintable():
        raise ProvisionError(f"secret {ref}: holds a line break or control character; env values are one line")
    return value


def resolve(node: NodeSpec) -> tuple[tuple[str, str], ...]:
    """``node``'s secrets as (NAME, value) pairs, for the file written on its host only."""
    return tuple((key, read(ref)) for key, ref in node.secrets)


def problems(plan: Plan) -> list[str]:
    """Every secret of ``plan`` that cannot be read now, one line each (no values)."""
    out = []
    for server, _, ref in plan.registries:
        try:
            read(ref)
        except ProvisionError as err:
            out.append(f"cloud.registries {server}: password: {err}")
    for node in plan.nodes:
        for key, ref in node.secrets:
            try:
                read(ref)
            except ProvisionError as err:
                out.append(f"node {node.name}: env {key}: {err}")
    return out


def check(plan: Plan) -> None:
    """Before ``up`` creates anything: every secret readable, else one error naming each."""
    found = problems(plan)
    if found:
        raise ProvisionError("; ".join(found))
