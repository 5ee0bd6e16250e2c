"""A tiny process supervisor for hosts without systemd (containers, WSL, test namespaces).

Why: a node must come back when it crashes, whether or not the host runs systemd. This file is
standard-library only and self-contained: provisioning copies it to ``<base>/bin`` on each host
and runs it with the host's ``python3``. Per service NAME in a run folder it keeps
``NAME.pid`` (the supervisor), ``NAME.child`` (the running process), ``NAME.log`` (its output)
and ``NAME.state`` (restart count, when the last few exits were). The child runs in its own session; on failure it is
restarted with exponential backoff (1 s doubling to 30 s, reset after 10 s of good running).
``NAME.log`` is rotated when it passes ``LOG_MAX_BYTES``: copied to ``NAME.log.1`` (the one
older file kept) and truncated in place, checked every second, so a chatty or attacked
service holds at most about twice that on disk (the child keeps its append-only descriptor).

    supervise.py start NAME --dir RUN -- ARGV...   idempotent: a running service is left alone
    supervise.py stop NAME --dir RUN               TERM the tree, KILL after a grace period
    supervise.py stop-all --dir RUN
    supervise.py status NAME --dir RUN             one JSON line
    supervise.py status-all --dir RUN              one JSON line per service ever started
    supervise.py probe --dir RUN                   "ros yes" if rospy imports, then "status JSON" lines
    supervise.py health NAME --dir RUN --check master|node|any|alive --master URI --timeout S
    supervise.py health-all --dir RUN --spec NAME=CHECK ... --master URI --timeout S

Stands alone: the helpers fogiac shares elsewhere (``fogiac.procs``: ``pid_alive``,
``stop_tree``, ``poll``) have their own copies here, because this file runs on hosts where
fogiac itself is not installed.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import FrameType
from typing import Any, BinaryIO

_GRACE = 5.0
_BACKOFF_MAX = 30.0
_GOOD_RUN = 10.0
LOG_MAX_BYTES = 10 * 1024 * 1024
_LOG_CHECK_S = 1.0
# A service whose program exited this many times within the window, and is not running now, is crash-looping:
# health says so at once instead of waiting out its timeout. At the backoff above, a program that exits at once
# is down for the 4th time ~7 s after its start, so a node that dies a few times while something it needs
# comes up still passes; one that keeps dying fails ``up`` in seconds (issue 35 item 6).
CRASH_LOOP_EXITS = 4
CRASH_LOOP_WINDOW_S = 60.0


def pid_alive(pid: int) -> bool:
    """The process exists and is not a zombie (a copy of fogiac.procs.pid_alive: this file stands alone)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:  # a zombie is not alive
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return True


def _start_time(pid: int) -> str | None:
    """When ``pid`` started (clock ticks since boot, field 22 of /proc/PID/stat): with the pid it
    names one process for good, unlike the command line, which the child's exec changes."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError):
        return None


def _age(pid: int) -> float | None:
    """Seconds since ``pid`` started (its start time against the machine's uptime), or None when gone."""
    started = _start_time(pid)
    try:
        uptime = float(Path("/proc/uptime").read_text().split()[0])
        return max(0.0, uptime - int(started or "") / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return None


def _write_pid(path: Path, pid: int) -> None:
    path.write_text(f"{pid} {_start_time(pid)}\n")


def _read_pid(path: Path) -> int | None:
    """The live process a pid file names, or None. A pid that was reused by an unrelated process
    (a stale file after a reboot or a crash) has another start time: never trusted, never signalled."""
    try:
        pid_text, started = path.read_text().split()
        pid = int(pid_text)
    except (OSError, ValueError):
        return None
    return pid if pid_alive(pid) and _start_time(pid) == started else None


def _ppid(pid: int) -> int | None:
    try:
        return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
    except (OSError, IndexError, ValueError):
        return None


def _descendants(root: int) -> list[int]:
    parents: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            ppid = _ppid(int(entry.name))
            if ppid is not None:
                parents.setdefault(ppid, []).append(int(entry.name))
    out, todo = [], [root]
    while todo:
        for child in parents.get(todo.pop(), []):
            out.append(child)
            todo.append(child)
    return out


def _in_tree(pid: int, root: int) -> bool:
    while pid and pid > 1:
        if pid == root:
            return True
        pid = _ppid(pid) or 0
    return False


def _kill_tree(pid: int, grace: float = _GRACE) -> None:
    """TERM the process group and every descendant (roslaunch puts nodes in new sessions).

    A copy of fogiac.procs.stop_tree (with its poll loop inline): this file stands alone.
    """
    tree = [pid] + _descendants(pid)
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for target in tree:
            try:
                os.killpg(target, sig) if target == pid else os.kill(target, sig)
            except (ProcessLookupError, PermissionError):
                pass
        deadline = time.monotonic() + grace
        while time.monotonic() < deadline and any(pid_alive(p) for p in tree):
            time.sleep(0.05)
        tree = [p for p in tree if pid_alive(p)]
        if not tree:
            return


class _Files:
    def __init__(self, run_dir: Path, name: str) -> None:
        self.pid = run_dir / f"{name}.pid"
        self.child = run_dir / f"{name}.child"
        self.log = run_dir / f"{name}.log"
        self.state = run_dir / f"{name}.state"


def _note(log: BinaryIO, text: str) -> None:
    log.write(f"[fogiac-supervise {time.strftime('%Y-%m-%dT%H:%M:%S')}] {text}\n".encode())
    log.flush()


def _rotate(path: Path, *, limit: int = LOG_MAX_BYTES) -> bool:
    """Copy ``path`` to ``path.1`` and empty it in place once it is over ``limit`` bytes (copytruncate:
    the child writes with O_APPEND, so its next line lands at the new end)."""
    try:
        if path.stat().st_size <= limit:
            return False
        older = path.with_name(path.name + ".1")
        with open(path, "rb") as src, open(older, "wb") as dst:
            while chunk := src.read(1 << 20):
                dst.write(chunk)
        os.truncate(path, 0)
    except OSError:
        return False
    return True


def _supervise(files: _Files, argv: list[str]) -> None:
    """The supervisor's main loop (runs daemonized)."""
    stopping = False
    child: subprocess.Popen | None = None

    def stop(signum: int, frame: FrameType | None) -> None:
        nonlocal stopping
        stopping = True
        if child is not None and child.poll() is None:
            _kill_tree(child.pid)

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    restarts, backoff = 0, 1.0
    exits: list[float] = []  # wall-clock times of the last CRASH_LOOP_EXITS exits, read by health()

    def note_state(pid: int) -> None:
        files.state.write_text(json.dumps({"restarts": restarts, "child": pid, "exits": exits}) + "\n")

    with open(files.log, "ab", buffering=0) as log:
        while not stopping:
            started = time.monotonic()
            child = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                     start_new_session=True)
            _write_pid(files.child, child.pid)
            note_state(child.pid)
            while True:
                try:
                    code = child.wait(timeout=_LOG_CHECK_S)
                    break
                except subprocess.TimeoutExpired:
                    if _rotate(files.log):
                        _note(log, f"log rotated: the earlier {LOG_MAX_BYTES // (1024 * 1024)} MiB+ are in "
                                   f"{files.log.name}.1")
            if stopping:
                break
            _kill_tree(child.pid, grace=1.0)
            if time.monotonic() - started > _GOOD_RUN:
                backoff = 1.0
            restarts += 1
            exits = [*exits, time.time()][-CRASH_LOOP_EXITS:]
            note_state(child.pid)  # at the exit, not at the restart: health sees a crash loop during the backoff
            _note(log, f"exited with {code}; restart {restarts} in {backoff:g}s")
            deadline = time.monotonic() + backoff
            while not stopping and time.monotonic() < deadline:
                time.sleep(0.05)
            backoff = min(backoff * 2, _BACKOFF_MAX)
        _note(log, "stopped")
    for path in (files.child, files.pid):
        path.unlink(missing_ok=True)


def start(run_dir: Path, name: str, argv: list[str]) -> str:
    files = _Files(run_dir, name)
    pid = _read_pid(files.pid)
    if pid is not None:
        return f"running {pid}"
    run_dir.mkdir(parents=True, exist_ok=True)
    files.pid.unlink(missing_ok=True)
    first = os.fork()
    if first:
        os.waitpid(first, 0)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            pid = _read_pid(files.pid)
            if pid is not None and files.child.exists():
                return f"started {pid}"
            time.sleep(0.02)
        return "started ?"
    os.setsid()
    if os.fork():
        os._exit(0)
    null = os.open(os.devnull, os.O_RDWR)
    for fd in (0, 1, 2):
        os.dup2(null, fd)
    os.closerange(3, 1024)
    _write_pid(files.pid, os.getpid())
    try:
        _supervise(files, argv)
    finally:
        os._exit(0)


def stop_many(run_dir: Path, names: list[str], *, timeout: float = 15.0) -> dict[str, str]:
    """Stop several services at once: TERM every supervisor, then wait for all of them together."""
    sups = {name: _read_pid(_Files(run_dir, name).pid) for name in names}
    children = {name: _read_pid(_Files(run_dir, name).child) for name in names}
    for pid in sups.values():
        if pid is not None:
            os.kill(pid, signal.SIGTERM)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and any(p is not None and pid_alive(p) for p in sups.values()):
        time.sleep(0.05)
    out = {}
    for name in names:
        files, pid = _Files(run_dir, name), sups[name]
        if pid is not None and pid_alive(pid):
            os.kill(pid, signal.SIGKILL)
        child = _read_pid(files.child)
        if child is not None:
            _kill_tree(child)
        for path in (files.child, files.pid):
            path.unlink(missing_ok=True)
        out[name] = "stopped" if pid is not None or children[name] is not None else "not running"
    return out


def stop(run_dir: Path, name: str, *, timeout: float = 15.0) -> str:
    return stop_many(run_dir, [name], timeout=timeout)[name]


def _state(files: _Files) -> dict:
    try:
        state = json.loads(files.state.read_text())
    except (OSError, ValueError):  # none yet, or being written this instant
        return {}
    return state if isinstance(state, dict) else {}


def _recent_exits(run_dir: Path, name: str, *, window: float = CRASH_LOOP_WINDOW_S) -> int:
    """How many times the service's program exited within the last ``window`` seconds (of those the
    supervisor keeps: at most CRASH_LOOP_EXITS)."""
    exits = _state(_Files(run_dir, name)).get("exits")
    now = time.time()
    return sum(1 for t in exits if isinstance(t, (int, float)) and now - t <= window) if isinstance(exits, list) else 0


def status(run_dir: Path, name: str) -> dict:
    files = _Files(run_dir, name)
    state = _state(files)
    pid = _read_pid(files.pid)
    child = _read_pid(files.child) if pid is not None else None
    # "running" means supervised: between a crash and its restart the child is briefly absent.
    out = {"name": name, "running": pid is not None, "pid": pid, "child": child, "restarts": state.get("restarts", 0)}
    # Crash-looping: restarted, and the program now is not running or has not yet run as long as a good run
    # (the backoff's reset); a supervisor that restarts its child forever still reads "running" above.
    age = _age(child) if child is not None else None
    if pid is not None and out["restarts"] and (age is None or age < _GOOD_RUN):
        out.update(crash_looping=True, last_line=_last_line(files.log))
    return out


def _registered_pids(master: str) -> dict[str, int]:
    # Lazily: xmlrpc.client doubles this script's start-up (~20 ms), paid by every start, stop and status.
    import xmlrpc.client  # noqa: PLC0415

    proxy = xmlrpc.client.ServerProxy(master)
    reply: Any = proxy.getSystemState("/fogiac_health")  # XML-RPC replies are untyped: [code, message, value]
    code, _, state = reply
    names = {n for group in state for _, nodes in group for n in nodes} - {"/rosout"}
    out: dict[str, int] = {}
    for name in names:
        lookup: Any = proxy.lookupNode("/fogiac_health", name)
        code, _, uri = lookup
        if code == 1:
            try:
                pid_reply: Any = xmlrpc.client.ServerProxy(uri).getPid("/fogiac_health")
                out[name] = int(pid_reply[2])
            except (OSError, xmlrpc.client.Error, ValueError):
                pass
    return out


# A service is healthy once its process has stayed up this long, the same process throughout: a program
# that exits at once is restarted by its supervisor (or systemd) and must not pass on a lucky moment.
STAYED_UP_S = 2.0
# fogiac's own ROS nodes (the relay's ends, the replicas' merge): never a container node's registration.
_OWN_NODES = "/fogiac_"


def health(run_dir: Path, name: str, *, check: str, master: str, timeout: float,
           pid: int | None = None, stayed_up: float = STAYED_UP_S) -> tuple[bool, str]:
    """Wait until the service is alive, has stayed up ``stayed_up`` seconds, and is registered with its master.

    ``master``: the master answers; ``node``: a process of the service's tree is a registered
    node; ``any``: some node other than fogiac's own is registered (containers: their processes are not
    our children); ``alive``: the process runs. ``pid`` names the process when systemd, not us, runs it.
    A supervised service that is not running and exited :data:`CRASH_LOOP_EXITS` times within
    :data:`CRASH_LOOP_WINDOW_S` is crash-looping: unhealthy now, not at the timeout (waiting it out only
    delayed the same verdict).
    """
    deadline = time.monotonic() + timeout
    why = "not checked"
    while True:
        child = (pid if pid and pid_alive(pid) else None) if pid is not None else status(run_dir, name)["child"]
        age = _age(child) if child is not None else None
        if child is None or age is None:
            why = "process not running"
            if pid is None and _recent_exits(run_dir, name) >= CRASH_LOOP_EXITS:
                return False, f"{why}; log: {_last_line(_Files(run_dir, name).log)}"
        else:
            ok, why = _registered(check, child, master)
            if ok and age >= stayed_up:
                return True, why
            if ok:
                why = f"pid {child} up {age:.1f}s of the {stayed_up:g}s it must stay up"
        if time.monotonic() >= deadline:
            return False, f"{why}; log: {_last_line(_Files(run_dir, name).log)}"
        time.sleep(0.2)


def _registered(check: str, child: int, master: str) -> tuple[bool, str]:
    """(whether the check holds for ``child`` now, what was seen)."""
    if check == "alive":
        return True, f"pid {child}"
    try:
        pids = _registered_pids(master)
    except (OSError, ValueError, _xmlrpc_error()) as err:
        return False, f"ROS master {master} not answering ({err})"
    if check == "master":
        return True, f"master up, pid {child}"
    mine = sorted(n for n, p in pids.items()
                  if (check == "any" and not n.startswith(_OWN_NODES)) or (check != "any" and _in_tree(p, child)))
    if mine:
        return True, "registered " + ",".join(mine)
    if check == "any":
        return False, f"no node but fogiac's own registered with {master}"
    return False, f"no node of pid {child} registered with {master}"


def _xmlrpc_error() -> type[Exception]:
    import xmlrpc.client  # noqa: PLC0415 (lazily, as in _registered_pids)

    return xmlrpc.client.Error


def _last_line(path: Path) -> str:
    """The program's last line (the supervisor's own notes skipped), from the log's last 64 KiB only."""
    try:
        with open(path, "rb") as log:
            log.seek(max(0, log.seek(0, os.SEEK_END) - 65536))
            text = log.read().decode(errors="replace")
        lines = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("[fogiac-supervise ")]
    except OSError:
        return "(no log)"
    return lines[-1].strip()[:200] if lines else "(empty)"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fogiac-supervise")
    parser.add_argument("action", choices=("start", "stop", "stop-all", "status", "status-all", "probe",
                                           "health", "health-all"))
    parser.add_argument("--spec", action="append", default=[], help="NAME=CHECK for health-all")
    parser.add_argument("name", nargs="?", default="")
    parser.add_argument("--dir", required=True, type=Path)
    parser.add_argument("--check", default="alive", choices=("alive", "master", "node", "any"))
    parser.add_argument("--pid", type=int, default=None)
    parser.add_argument("--master", default="http://127.0.0.1:11311")
    parser.add_argument("--timeout", type=float, default=30.0)
    argv = list(sys.argv[1:] if argv is None else argv)
    command = argv[argv.index("--") + 1:] if "--" in argv else []
    args = parser.parse_args(argv[: argv.index("--")] if "--" in argv else argv)
    if args.action == "start":
        if not args.name or not command:
            parser.error("start needs NAME -- ARGV")
        print(start(args.dir, args.name, command))
    elif args.action == "stop":
        print(stop(args.dir, args.name))
    elif args.action == "stop-all":
        names = sorted(p.stem for p in args.dir.glob("*.pid")) if args.dir.is_dir() else []
        for name, outcome in stop_many(args.dir, names).items():
            print(f"{name}: {outcome}")
    elif args.action == "status":
        print(json.dumps(status(args.dir, args.name)))
    elif args.action in ("status-all", "probe"):
        prefix = "status " if args.action == "probe" else ""
        if args.action == "probe":  # one interpreter start answers both of provisioning's questions
            if importlib.util.find_spec("rospy") is not None:
                print("ros yes")
        found = {p.stem for p in args.dir.glob("*.pid")} | {p.stem for p in args.dir.glob("*.state")}
        for name in sorted(found):
            print(prefix + json.dumps(status(args.dir, name)))
    elif args.action == "health-all":
        deadline = time.monotonic() + args.timeout
        failed = 0
        for spec in args.spec:
            name, _, check = spec.partition("=")
            ok, detail = health(args.dir, name, check=check, master=args.master,
                                timeout=max(0.0, deadline - time.monotonic()))
            failed += not ok
            print(f"{name} {'ok' if ok else 'fail'} {detail}")
        return 1 if failed else 0
    else:
        ok, detail = health(args.dir, args.name, check=args.check, master=args.master, timeout=args.timeout,
                            pid=args.pid)
        print(detail)
        return 0 if ok else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
