"""The host's beacon: every client that connects gets ``<greeting> <seq> <interval>`` each interval.
Shipped to the host as a file and run with its Python (standard library only)."""

from __future__ import annotations

import argparse
import socketserver
import time


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--listen", default="127.0.0.1")
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--interval", type=float, required=True)
    parser.add_argument("--greeting", default="beat")
    args = parser.parse_args()

    class Beat(socketserver.BaseRequestHandler):
        def handle(self) -> None:
            seq = 0
            while True:
                seq += 1
                try:
                    self.request.sendall(f"{args.greeting} {seq} {args.interval:g}\n".encode())
                except OSError:
                    return
                time.sleep(args.interval)

    socketserver.ThreadingTCPServer.allow_reuse_address = True
    socketserver.ThreadingTCPServer.daemon_threads = True
    with socketserver.ThreadingTCPServer((args.listen, args.port), Beat) as server:
        server.serve_forever()


if __name__ == "__main__":
    main()
