"""Why a test that runs real containers cannot run here, or None: root, podman, and its base image."""

from __future__ import annotations

import os
import shutil
import subprocess
from functools import cache


@cache
def podman_missing(image: str, what: str) -> str | None:
    """``what``: the image in words, for the skip reason ("the test base image").

    Cached, as ``ros_missing`` is: asked at collection by several modules in every worker.
    """
    if os.geteuid() != 0:
        return "runs podman as root"
    if shutil.which("podman") is None:
        return "needs podman (apt-get install podman runc podman-docker)"
    if subprocess.run(["podman", "image", "exists", image], capture_output=True).returncode:
        return f"needs {what} {image} (bash .ci/containers.sh builds it)"
    return None
