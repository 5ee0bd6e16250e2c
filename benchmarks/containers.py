"""Benchmark: ``fogiac up`` on the container runtime, first (images built) against no-change.

The first ``up`` of the motion-planning example with ``runtime: container`` on the local
target builds the workload's image from its recipe (pip installs OMPL and its friends) and a
``build:`` node's image from a two-line Dockerfile; the second ``up`` finds both digests and
changes nothing. Printed: both wall times, their ratio, and the images' sizes against the base
they were built on. Needs root, podman and the base image from ``.ci/containers.sh``; it
removes the workload's cached images first, so the next test run rebuilds them once.

    .venv/bin/python benchmarks/containers.py
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
BASE = "docker.io/library/ros:noetic-ros-core"


def podman(*args: str) -> str:
    return subprocess.run(["podman", *args], capture_output=True, text=True, check=True).stdout


def fogiac(*args: str, env: dict[str, str]) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "fogiac", *args], check=True, env=env, cwd=REPO,
                   stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def size_mb(image: str) -> float:
    return int(podman("image", "inspect", "--format", "{{.Size}}", image).strip()) / 1e6


def main() -> int:
    from fogiac.procs import free_port

    for repo in ("fogiac/motion_planning", "fogiac/bench-containers-dev-app"):
        tags = podman("images", "--format", "{{.Repository}}:{{.Tag}}", f"localhost/{repo}").split()
        if tags:
            podman("rmi", "--force", *tags)
    with tempfile.TemporaryDirectory(prefix="fogiac-bench-") as tmp:
        root = Path(tmp)
        (root / "app").mkdir()
        (root / "app" / "Dockerfile").write_text(
            'FROM ros:noetic-ros-core\nCMD ["rostopic", "pub", "-r", "1", "/bench", "std_msgs/String", "data: up"]\n')
        manifest = root / "fogiac.yaml"
        manifest.write_text(f"""name: bench-containers
cloud: {{provider: local, runtime: container}}
edge: {{ros_master: "http://127.0.0.1:{free_port()}"}}
nodes:
  - name: planner
    machine: c5.xlarge
    workload: motion_planning
  - name: app
    machine: t3.small
    build: {{context: app}}
""")
        env = {**os.environ, "FOGIAC_STATE_DIR": str(root / "state")}
        try:
            first = fogiac("up", str(manifest), "--target", "local", "--yes", "--start-edge-master", env=env)
            again = fogiac("up", str(manifest), "--target", "local", "--yes", env=env)
            images = dict(line.split() for line in podman(
                "ps", "--filter", "label=fogiac.stack=bench-containers-dev", "--format",
                "{{.Names}} {{.Image}}").splitlines() if "ros-master" not in line)
        finally:
            fogiac("down", str(manifest), "--target", "local", "--yes", env=env)
    base = size_mb(BASE)
    print(json.dumps({
        "first_up_s": round(first, 2), "no_change_up_s": round(again, 2), "ratio": round(first / again, 1),
        "base_mb": round(base), "images": {name: {"image": image, "mb": round(size_mb(image)),
                                                  "over_base_mb": round(size_mb(image) - base)}
                                           for name, image in sorted(images.items())},
    }, indent=2))
    print(f"first up (builds) {first:.1f} s vs no-change up {again:.2f} s: {first / again:.0f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
