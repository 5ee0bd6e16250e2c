"""Process liveness, shared by the state lock, the planner's workers and the tests.

(``fogiac/provision/supervise.py`` keeps its own copy: it is copied to hosts and must stand alone.)
"""

from __future__ import annotations

import os
from pathlib import Path


def pid_alive(pid: int) -> bool:
    """The process exists and is neither a zombie nor dead (states Z and X)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except (OSError, IndexError):
        return True
