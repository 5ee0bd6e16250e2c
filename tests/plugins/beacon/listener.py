"""The edge's side: dial every host's beacon (``--connect HOST=ADDRESS:PORT``), count the beats, and
write them to ``--stats`` (atomically) every half second: what ``status`` reads."""

from __future__ import annotations

import argparse
import json
import os
import socket
import threading
import time
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--stats", required=True)
    parser.add_argument("--connect", action="append", default=[])
    args = parser.parse_args()
    seen: dict[str, dict] = {}
    lock = threading.Lock()

    def follow(host: str, address: str) -> None:
        name, _, port = address.rpartition(":")
        while True:
            try:
                with socket.create_connection((name, int(port)), timeout=5) as conn, conn.makefile() as lines:
                    for line in lines:
                        word, seq, interval = line.split()
                        with lock:
                            seen[host] = {"connected": True, "beats": int(seq), "word": word,
                                          "interval_s": float(interval), "at": time.time()}
            except (OSError, ValueError):
                pass
            with lock:
                seen.setdefault(host, {})["connected"] = False
            time.sleep(0.2)

    for pair in args.connect:
        host, _, address = pair.partition("=")
        threading.Thread(target=follow, args=(host, address), daemon=True).start()
    stats = Path(args.stats)
    while True:
        with lock:
            text = json.dumps({"hosts": seen})
        stats.with_suffix(".tmp").write_text(text)
        os.replace(stats.with_suffix(".tmp"), stats)
        time.sleep(0.5)


if __name__ == "__main__":
    main()
