"""Start ``fogiac`` commands as forks of one Python that has already imported fogiac (a fork server).

Why: the ``kill -9`` walks (tests/targets/aws/test_shared_state_kill.py, tests/test_store_kill.py) run the
real command dozens of times, each time killed by its own ``SIGKILL`` after its Nth store write, and each of
those processes paid Python's start and fogiac's imports (typer, pydantic, the manifest's schema, boto3,
cryptography): 1-5 s each on a loaded two-core runner, most of the walks' time. Here one server process
imports them once; each command is a fresh ``fork`` of it that becomes the command:

- a process of its own (its own pid, the one the lock names; its own session, so ``killpg`` reaches what it
  started), with the caller's working directory, environment (``os.environ`` replaced whole) and
  ``sys.argv``, stdin from ``/dev/null`` and stdout and stderr into one file, as a pipe with
  ``stderr=STDOUT`` would merge them;
- that runs ``fogiac/__main__.py`` as ``python -m fogiac`` does (``runpy``, ``__main__`` and ``sys.path[0]``
  as that would set them) and ends as that process would: its exit status, atexit handlers, or the signal
  that killed it (``-9``).

Nothing of a command reaches the server or the next command: the server only imports (no fogiac code runs
in it, no thread is started: a fork copies only the thread that forks), and each fork exits when its
command does. Modules fogiac imports lazily and the server did not are imported by the fork, as the real
command would. Protocol (one JSON object a line): the caller writes ``{"argv", "cwd", "env", "out"}``; the
server answers ``{"pid": N}`` once the fork runs and ``{"status": S}`` when it ended
(``os.waitstatus_to_exitcode``: ``-9`` for a SIGKILL).
"""

from __future__ import annotations

import gc
import importlib
import json
import os
import runpy
import select
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

# What the walks' commands (up, down, status, state show/unlock/migrate; the folder and the S3 store, the
# local target) import, heaviest first; a name that fails to import is left to the command.
PRELOAD = (
    "fogiac.cli", "fogiac.cli._common", "fogiac.cli.deploy", "fogiac.cli.state", "fogiac.cli.plan",
    "fogiac.lifecycle.sequence", "fogiac.lifecycle.edge", "fogiac.provision.runner", "fogiac.provision.steps",
    "fogiac.targets.local", "fogiac.targets.local.target", "fogiac.certs", "fogiac.sealed", "fogiac.state",
    "fogiac.store", "fogiac.plan.compile", "fogiac.plan.review", "fogiac.manifest.schema",
    "fogiac.targets.aws.s3store", "boto3", "boto3.session", "botocore.session", "botocore.client",
    "botocore.args", "botocore.endpoint", "botocore.httpsession", "botocore.parsers", "botocore.serialize",
    "botocore.handlers", "botocore.regions", "s3transfer", "xmlrpc.client", "typer._adapters",
    "typer._click.decorators", "fogiac.net.relay.middleware", "fogiac.targets.local.manifest", "lz4.frame",
    "zstandard",
)


def _preload() -> None:
    for name in PRELOAD:
        try:
            importlib.import_module(name)
        except Exception:  # noqa: BLE001 (the command imports it itself, and says what failed)
            continue
    if threading.active_count() != 1:  # a fork keeps only the forking thread: state another held would be lost
        raise SystemExit(f"forkserver: an import started a thread ({threading.enumerate()}); cannot fork safely")


def _become(request: dict[str, Any]) -> None:
    """In the fork: become ``python -m fogiac ARGV`` run in ``cwd`` with ``env``; never returns (the
    command's SystemExit, or its uncaught exception, ends this interpreter as it would end that one)."""
    os.setsid()
    out = os.open(request["out"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    null = os.open(os.devnull, os.O_RDONLY)
    os.dup2(null, 0)
    os.dup2(out, 1)
    os.dup2(out, 2)
    os.close(out)
    os.close(null)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    os.chdir(request["cwd"])
    os.environ.clear()
    os.environ.update(request["env"])
    sys.path[0] = request["cwd"]  # python -m puts the working directory first
    sys.argv = ["fogiac", *request["argv"]]
    runpy.run_module("fogiac", run_name="__main__", alter_sys=True)
    raise SystemExit(0)


def serve() -> None:
    _preload()
    # What the imports made is never collectable: out of the collector's sight, a fork's collections (at its
    # exit above all) no longer walk it, touching, and so copying, every page of it (0.3 s a command of the
    # 0.45 s a fork took, here).
    gc.freeze()
    print(json.dumps({"ready": os.getpid()}), flush=True)
    for line in sys.stdin:
        request = json.loads(line)
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:
            _become(request)
        print(json.dumps({"pid": pid}), flush=True)
        _, status = os.waitpid(pid, 0)
        print(json.dumps({"status": os.waitstatus_to_exitcode(status)}), flush=True)


class ForkServer:
    """The caller's end: :meth:`run` one command at a time (``argv`` after ``fogiac``)."""

    def __init__(self, env: dict[str, str], cwd: Path) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "tests.support.forkserver"], cwd=cwd, env=env,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
        self._read(300)  # ready

    def _read(self, timeout: float) -> dict[str, Any] | None:
        stdout: IO[str] = self.proc.stdout  # type: ignore[assignment]
        if not select.select([stdout], [], [], timeout)[0]:
            return None
        line = stdout.readline()
        if not line:
            raise RuntimeError(f"the fork server ended ({self.proc.wait()})")
        answer: dict[str, Any] = json.loads(line)
        return answer

    def run(self, argv: list[str], *, cwd: Path, env: dict[str, str], out: Path,
            timeout: float = 300) -> tuple[int, str, int]:
        """The command's exit status (``-9``: it killed itself), what it said, and its pid; a command still
        running after ``timeout`` seconds is killed with what it started (its session)."""
        stdin: IO[str] = self.proc.stdin  # type: ignore[assignment]
        stdin.write(json.dumps({"argv": argv, "cwd": str(cwd), "env": env, "out": str(out)}) + "\n")
        stdin.flush()
        started = self._read(60)
        if started is None:
            raise RuntimeError("the fork server did not start the command")
        pid = int(started["pid"])
        ended = self._read(timeout)
        if ended is None:
            os.killpg(pid, signal.SIGKILL)
            ended = self._read(60) or {"status": -signal.SIGKILL}
        return int(ended["status"]), out.read_text(errors="replace"), pid

    def close(self) -> None:
        if self.proc.stdin:
            self.proc.stdin.close()
        try:
            self.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        if self.proc.stdout:
            self.proc.stdout.close()


def forks_fixture() -> Iterator[ForkServer]:
    """A module's fork server (``forks = pytest.fixture(scope="module")(forks_fixture)`` in a test module):
    started with the test's environment and this checkout first on ``PYTHONPATH``, closed after the module."""
    repo = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(repo), os.environ.get("PYTHONPATH")]))}
    server = ForkServer(env, repo)
    try:
        yield server
    finally:
        server.close()


if __name__ == "__main__":
    serve()
