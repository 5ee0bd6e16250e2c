"""A shared request/reply node stood in on plain Zenoh keys, as rmw_zenoh lays them out, in its own process:

    python -m tests.net.zenoh.echonode PORT --request /plan_request --reply /plan_result

It answers every request (``<domain>/<request>/<type>/<hash>``) with the same message on the reply topic
(``<domain>/<reply>/<type>/<hash>``): header stamp and frame_id unchanged, as a planner answers a goal.
"""

from __future__ import annotations

import argparse
import json
import signal
import threading

import zenoh


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("port", type=int)
    parser.add_argument("--request", required=True)
    parser.add_argument("--reply", required=True)
    parser.add_argument("--delay", type=float, default=0.0, help="answer this many seconds later (requests overlap)")
    args = parser.parse_args()
    config = {"mode": "client", "connect": {"endpoints": [f"tcp/127.0.0.1:{args.port}"]},
              "scouting": {"multicast": {"enabled": False}}}
    session = zenoh.open(zenoh.Config.from_json5(json.dumps(config)))
    request, reply = args.request.strip("/"), args.reply.strip("/")

    def answer(key: str, payload: bytes, encoding: zenoh.Encoding, attachment: zenoh.ZBytes | None) -> None:
        domain, *_, kind, digest = key.split("/")
        session.put(f"{domain}/{reply}/{kind}/{digest}", payload, encoding=encoding, attachment=attachment)

    def later(sample: zenoh.Sample) -> None:
        what = (str(sample.key_expr), sample.payload.to_bytes(), sample.encoding, sample.attachment)
        threading.Timer(args.delay, answer, what).start()

    session.declare_subscriber(f"*/{request}/*/*", later)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    print("ready", flush=True)
    stop.wait()
    session.close()


if __name__ == "__main__":
    main()
