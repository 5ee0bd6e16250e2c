"""Liveness and port choice shared by the state lock, the local target and the tests."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import signal
import time

from fogiac.procs import _ephemeral_low, cpu_seconds, descendants, free_port, pid_alive, poll, stop_tree


def test_free_port_is_bindable_and_outside_the_ephemeral_range() -> None:
    low = _ephemeral_low()
    for _ in range(20):
        port = free_port()
        assert port < low
        with socket.socket() as sock:
            sock.bind(("127.0.0.1", port))


def test_a_zombie_is_not_alive_and_a_running_process_is() -> None:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    while Path(f"/proc/{child.pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z":
        pass  # exited, not yet reaped: a zombie
    assert not pid_alive(child.pid)
    child.wait()
    assert not pid_alive(child.pid)
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        assert pid_alive(sleeper.pid)
    finally:
        sleeper.kill()
        sleeper.wait()


def test_poll_returns_the_first_answer_and_backs_off_within_the_deadline() -> None:
    clock = [0.0]
    pauses: list[float] = []

    def sleep(seconds: float) -> None:
        pauses.append(seconds)
        clock[0] += seconds

    answers = iter([None, None, None, "up"])
    assert poll(lambda: next(answers), timeout=10, interval=0.1, backoff=2.0, sleep=sleep) == "up"
    assert pauses == [0.1, 0.2, 0.4]


def test_poll_gives_up_at_the_deadline_after_a_last_look() -> None:
    calls: list[float] = []
    start = time.monotonic()
    assert poll(lambda: calls.append(time.monotonic() - start), timeout=0.3, interval=0.05, max_interval=0.1) is None
    assert calls[0] < 0.05 and calls[-1] >= 0.3  # at once, ..., and once more at the deadline


def test_stop_tree_ends_a_process_and_its_children_even_one_that_ignores_term() -> None:
    script = ("import signal, subprocess, sys, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); "
              "subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)']); time.sleep(60)")
    parent = subprocess.Popen([sys.executable, "-c", script], start_new_session=True)
    children: list[int] = []
    while not children:
        children = descendants(parent.pid)
    stop_tree(parent.pid, grace=0.5)
    parent.wait(timeout=10)
    assert parent.returncode == -signal.SIGKILL  # TERM was ignored, so the grace ran out
    assert all(not pid_alive(pid) for pid in children)


def test_cpu_seconds_counts_a_busy_process_and_is_zero_once_it_is_gone() -> None:
    child = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        assert poll(lambda: cpu_seconds(child.pid) >= 0.05 or None, timeout=60, interval=0.05) is True
    finally:
        child.kill()
        child.wait()
    assert cpu_seconds(child.pid) == 0.0
