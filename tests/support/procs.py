"""The processes fogiac's supervisor started under a state folder, read from its pid files.

A supervisor pid file holds ``PID STARTTIME`` (the start time proves the pid is still the process
that was started); ``.child`` files hold the supervised child's pid the same way.
"""

from __future__ import annotations

from pathlib import Path


def started_pids(state: Path) -> list[int]:
    """Every pid a ``.pid`` or ``.child`` file under ``state`` names."""
    pids = []
    for path in [*state.rglob("*.pid"), *state.rglob("*.child")]:
        try:
            pids.append(int(path.read_text().split()[0]))
        except (OSError, ValueError, IndexError):
            continue
    return pids


def alive(pid: int) -> bool:
    """Running, not a zombie waiting to be reaped."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def alive_pids(state: Path) -> list[int]:
    """The started pids that still run."""
    return [pid for pid in started_pids(state) if alive(pid)]
