"""The heavy optional extras, imported in one place each, failing in one line that names the extra.

fogiac's core (validate, plan's compile, the relay) needs none of these. A command that does
calls :func:`need` where it starts its work, not at module import, so ``fogiac validate``
stays fast and a missing extra is a one-line error, not a traceback::

    fabric = need("fabric", extra="ssh")
"""

from __future__ import annotations

import importlib
from types import ModuleType

from fogiac.errors import MissingExtra

# module -> the fogiac extra that installs it (pyproject.toml's [project.optional-dependencies]); a
# target's own SDKs are named by the target (the aws target's fogiac.targets.aws.sdk passes extra=).
EXTRAS: dict[str, str] = {
    "fabric": "ssh", "paramiko": "ssh",
    "zenoh": "ros2", "zenoh_ros2_sdk": "ros2",
    "torch": "workloads", "ompl": "workloads", "fcl": "workloads", "trimesh": "workloads",
    "matplotlib": "workloads", "numpy": "workloads", "cv2": "workloads", "gtsam": "workloads",
}


def need(module: str, *, extra: str | None = None) -> ModuleType:
    """Import ``module`` (dotted names too); if it is missing, one line naming the extra to install."""
    try:
        return importlib.import_module(module)
    except ImportError as err:
        top = module.split(".")[0]
        name = extra or EXTRAS.get(top, "all")
        raise MissingExtra(f"{top} is not installed ({err}); install it with: pip install 'fogiac[{name}]'") from None
