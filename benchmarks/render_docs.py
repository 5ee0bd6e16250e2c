"""Build the documentation site and look at it: screenshots of its pages in headless Chromium.

    .venv/bin/python benchmarks/render_docs.py [--out benchmarks/out/docs] [PAGE ...]

Runs ``mkdocs build --strict`` into ``OUT/site``, serves it on a free loopback port and has
Chromium (Debian's ``chromium`` package: ``apt-get install chromium``) take one PNG per page:
the home page and the manifest reference unless pages are named (paths under the site, such as
``reference/cli/``). Not part of the tests: a person looks at the PNGs. Prints each file written.
"""

from __future__ import annotations

import argparse
import functools
import http.server
import os
import shutil
import socket
import subprocess
import sys
import threading
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PAGES = ("", "reference/manifest/")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - the base class's name
        pass


def _browser() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    sys.exit("error: no Chromium on PATH; install Debian's package: apt-get install chromium")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks" / "out" / "docs")
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=1600)
    parser.add_argument("pages", nargs="*", default=list(PAGES))
    args = parser.parse_args()
    browser = _browser()
    site = args.out / "site"
    args.out.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    mkdocs = Path(sys.executable).with_name("mkdocs")
    subprocess.run([str(mkdocs), "build", "--strict", "--site-dir", str(site)], cwd=REPO, env=env, check=True,
                   stdout=subprocess.DEVNULL)
    port = _free_port()
    handler = functools.partial(_Quiet, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", port), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        for page in args.pages:
            name = page.strip("/").replace("/", "-") or "home"
            png = args.out / f"{name}.png"
            subprocess.run([browser, "--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                            f"--window-size={args.width},{args.height}", f"--screenshot={png}",
                            f"http://127.0.0.1:{port}/{page}"], check=True, capture_output=True, timeout=120)
            print(png)
    finally:
        server.shutdown()


if __name__ == "__main__":
    main()
