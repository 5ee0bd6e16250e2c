"""Where the engine keeps a stack's Pulumi state: a file backend in the stack's folder, secrets under a
passphrase, and the pinned Pulumi CLI that does the work.

State stays on the user's disk (``<stack folder>/pulumi``), or in the shared state store when one is
configured (``FOGIAC_STATE_URL``, the manifest's ``state:``: the same ``s3://`` bucket and prefix);
secrets are encrypted with a passphrase (``$PULUMI_CONFIG_PASSPHRASE``, else a generated 0600 file, which
a shared store keeps among the stack's files), so no Pulumi account is needed.
"""

from __future__ import annotations

import os
import re
import secrets
import shutil
import subprocess
from pathlib import Path
from types import ModuleType

from fogiac import extras
from fogiac.certs import write_private
from fogiac.pulumi_engine.errors import EngineError
from fogiac.state import StackState

# The one place the Pulumi CLI version is pinned: the release matching the pulumi SDK in use.
PULUMI_CLI_VERSION = "3.272.0"
INSTALL = f"curl -fsSL https://get.pulumi.com | sh -s -- --version {PULUMI_CLI_VERSION}"
PASSPHRASE_FILE = "pulumi-passphrase"
BACKEND_DIR = "pulumi"  # in the stack folder: the file backend's root


def need(module: str) -> ModuleType:
    """The Pulumi SDK (a cloud's target checks its own extra first, so its users see that one named)."""
    return extras.need(module, extra="pulumi")


def backend_dir(stack: str, *, create: bool = True) -> Path:
    return StackState(stack).target_file(BACKEND_DIR, create=create)


def shared_backend(stack: str) -> str | None:
    """The backend URL of a shared state store (``s3://BUCKET/PREFIX``: Pulumi keeps ``.pulumi/`` there, beside
    the stacks' records), so every member and CI preview against what is deployed; None: the stack folder's."""
    url = getattr(StackState(stack).store, "backend_url", None)
    return url if isinstance(url, str) and url else None


def pulumi_cli() -> Path:
    """The Pulumi CLI on PATH (or where its installer puts it), at least the pinned version."""
    found = shutil.which("pulumi") or next(
        (str(p) for p in [Path.home() / ".pulumi" / "bin" / "pulumi"] if p.is_file() and os.access(p, os.X_OK)), None)
    if found is None:
        raise EngineError(f"the Pulumi CLI is not installed (fogiac needs {PULUMI_CLI_VERSION}); "
                          f"install it with: {INSTALL}")
    try:
        out = subprocess.run([found, "version"], capture_output=True, text=True, timeout=30, check=True).stdout
    except (OSError, subprocess.SubprocessError) as err:
        raise EngineError(f"the Pulumi CLI at {found} does not run ({err}); reinstall it with: {INSTALL}") from None
    match = re.search(r"(\d+)\.(\d+)\.(\d+)", out)
    have = tuple(int(x) for x in match.groups()) if match else (0, 0, 0)
    want = tuple(int(x) for x in PULUMI_CLI_VERSION.split("."))
    if have[0] != want[0] or have < want:
        raise EngineError(f"the Pulumi CLI at {found} is {'.'.join(map(str, have))}, fogiac needs "
                          f"{PULUMI_CLI_VERSION} or a later 3.x; install it with: {INSTALL}")
    return Path(found)


def passphrase(stack: str) -> str:
    """The secrets passphrase: from the environment, else the stack's generated 0600 file."""
    given = os.environ.get("PULUMI_CONFIG_PASSPHRASE")
    if given is not None:
        return given
    given_file = os.environ.get("PULUMI_CONFIG_PASSPHRASE_FILE")
    if given_file:
        return Path(given_file).read_text().strip()
    path = StackState(stack).target_file(PASSPHRASE_FILE, create=True)
    if not path.exists():
        write_private(path, secrets.token_urlsafe(32).encode())
    return path.read_text().strip()


def workspace_env(stack: str) -> dict[str, str]:
    """What the Pulumi CLI needs: the backend (the shared store's, else a folder), the passphrase, no update nagging."""
    url = shared_backend(stack)
    if url is None:
        backend = backend_dir(stack)
        backend.mkdir(mode=0o700, exist_ok=True)
        url = backend.as_uri()
    return {
        "PULUMI_BACKEND_URL": url,
        "PULUMI_CONFIG_PASSPHRASE": passphrase(stack),
        "PULUMI_SKIP_UPDATE_CHECK": "true",
        "PULUMI_AUTOMATION_API_SKIP_VERSION_CHECK": "false",
    }
