"""The stratus platform: it runs pods, each a few processes it starts, records and stops on its own.

What a managed container service does for its tenants, on this machine: every process of a pod runs
in a session of its own (so the platform finds everything it started, children included, by session),
its output goes to a log in the pod's folder, and the platform's record (a JSON file, as a service's
API would hold it) says which pods run with which sessions. Nothing here is fogiac's supervisor.
"""

from __future__ import annotations

import os
import signal
import subprocess
import time
import uuid
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fogiac.state import read_json, write_json_atomic

STOP_TIMEOUT_S = 15.0
_STARTED: dict[int, subprocess.Popen[bytes]] = {}  # the platform's own children, reaped when they stop


@dataclass(frozen=True)
class Container:
    """One process of a pod: its name, its command line, its environment."""

    name: str
    argv: tuple[str, ...]
    env: Mapping[str, str]


class Platform:
    """Pods by name in ``record`` (a JSON file): ``{name: {id, folder, sessions: {container: pid}, ...}}``."""

    def __init__(self, record: Path) -> None:
        self.record = record

    def pods(self) -> dict[str, Any]:
        return read_json(self.record) or {}

    def start(self, name: str, folder: Path, containers: Sequence[Container], *, ready: Any = None,
              facts: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Run ``containers`` in order, each in a session of its own; ``ready(container)`` is called after
        each (to wait for what the next needs). The pod is recorded before its first process starts."""
        pod: dict[str, Any] = {"id": f"pod-{uuid.uuid4().hex[:10]}", "folder": str(folder), "sessions": {},
                               **dict(facts or {})}
        self._put(name, pod)
        for container in containers:
            with open(folder / f"{container.name}.log", "ab") as log:
                proc = subprocess.Popen(list(container.argv), env=dict(container.env), cwd=folder,
                                        stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                        start_new_session=True)
            _STARTED[proc.pid] = proc
            pod["sessions"][container.name] = proc.pid
            self._put(name, pod)
            if ready is not None:
                ready(container)
        return pod

    def running(self, name: str) -> bool:
        """Every process the pod started still runs."""
        pod = self.pods().get(name)
        return pod is not None and all(_alive(pid) for pid in pod["sessions"].values())

    def stop(self, name: str) -> list[int]:
        """Stop every process of the pod's sessions (TERM, then KILL past the timeout); the pids still
        running afterwards (none, when it worked). The pod leaves the record once nothing of it runs."""
        pod = self.pods().get(name)
        if pod is None:
            return []
        sessions = set(pod["sessions"].values())
        for sid in sessions:
            _signal_group(sid, signal.SIGTERM)
        deadline = time.monotonic() + STOP_TIMEOUT_S
        while members(sessions) and time.monotonic() < deadline:
            _reap(sessions)
            time.sleep(0.1)
        for pid in members(sessions):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        _reap(sessions)
        left = members(sessions)
        if not left:
            pods = self.pods()
            pods.pop(name, None)
            write_json_atomic(self.record, pods)
        return left

    def _put(self, name: str, pod: Mapping[str, Any]) -> None:
        write_json_atomic(self.record, {**self.pods(), name: dict(pod)})


def _signal_group(pgid: int, sig: signal.Signals) -> None:
    try:
        os.killpg(pgid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def _reap(sessions: set[int]) -> None:
    for pid in list(sessions):
        proc = _STARTED.get(pid)
        if proc is not None and proc.poll() is not None:
            _STARTED.pop(pid, None)


def _stat(pid: str) -> list[str] | None:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None


def _alive(pid: int) -> bool:
    fields = _stat(str(pid))
    return fields is not None and fields[0] != "Z"


def members(sessions: set[int]) -> list[int]:
    """The live (not zombie) processes of ``sessions``, found by session id: children included."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        fields = _stat(entry.name)  # state, ppid, pgrp, session, ...
        if fields is not None and fields[0] != "Z" and int(fields[3]) in sessions:
            found.append(int(entry.name))
    return found
