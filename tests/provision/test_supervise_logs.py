"""Service logs do not grow without bound (issue 26 item 7): the supervisor that runs every service on
hosts without systemd (and the edge's relays, routers and master) rotates its log. A real supervised
process writing far more than the limit; the files on disk afterwards."""

from __future__ import annotations

import sys
from pathlib import Path

from fogiac.procs import poll
from fogiac.provision import supervise

CHUNK = 1024 * 1024
WRITTEN = 3 * supervise.LOG_MAX_BYTES  # 30 MiB, a MiB every 50 ms
CHATTY = f"""
import sys, time
line = b"x" * 1023 + b"\\n"
for i in range({WRITTEN // CHUNK}):
    sys.stdout.buffer.write(line * 1024)
    sys.stdout.flush()
    time.sleep(0.05)
sys.stdout.buffer.write(b"done\\n")
sys.stdout.flush()
time.sleep(600)
"""


def test_a_chatty_services_log_is_rotated_and_its_newest_lines_kept(tmp_path: Path) -> None:
    supervise.start(tmp_path, "chatty", [sys.executable, "-c", CHATTY])
    log, older = tmp_path / "chatty.log", tmp_path / "chatty.log.1"
    try:
        def done() -> bool | None:  # the last line, in the log or, rotated since, at the end of the older one
            tails = [p.read_bytes()[-256:] for p in (log, older) if p.exists()]
            return True if any(b"done\n" in t for t in tails) else None

        assert poll(done, timeout=60), "the service never finished writing"
        on_disk = log.stat().st_size + (older.stat().st_size if older.exists() else 0)
        assert older.exists(), "no rotation"
        assert on_disk < WRITTEN - supervise.LOG_MAX_BYTES // 2, on_disk  # the oldest were let go
        kept = older.read_bytes()
        assert kept.split(b"\n", 1)[0].startswith((b"x" * 1023, b"[fogiac-supervise"))  # whole lines from the start
    finally:
        supervise.stop(tmp_path, "chatty")
