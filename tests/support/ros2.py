"""A stand-in ROS 2 installation for native-runtime tests: no ROS 2 is packaged for this Debian.

Provisioning asks a ROS 2 host (or its ROS image) for ``ros2`` and ``ros2 pkg prefix rmw_zenoh_cpp``;
this folder answers that one question as the real CLI does (the prefix of an installed package,
else exit 1), and its ``setup.bash`` puts it on PATH as /opt/ros/<distro>/setup.bash does.
``.ci/containers.sh`` lays it out at /opt/ros/jazzy in the ROS 2 stand-in image. The nodes
themselves are zenoh-ros2-sdk stand-ins, which need nothing from it.
"""

from __future__ import annotations

from pathlib import Path

ROS2_CLI = """#!/bin/sh
# stand-in for ROS 2's CLI: `ros2 pkg prefix NAME` only
prefix=$(dirname "$(dirname "$(readlink -f "$0")")")
if [ "$1 $2" = "pkg prefix" ] && [ -f "$prefix/share/$3/package.xml" ]; then echo "$prefix"; exit 0; fi
echo "Package not found" >&2
exit 1
"""


SETUP = """# stand-in for /opt/ros/<distro>/setup.bash
_fogiac_ros2=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
export PATH="$_fogiac_ros2/bin:$PATH" AMENT_PREFIX_PATH="$_fogiac_ros2"
"""


def standin_ros2(root: Path, *, packages: tuple[str, ...] = ("rmw_zenoh_cpp",)) -> Path:
    """Lay the installation out under ``root``; returns its bin folder (put it first on PATH)."""
    (root / "bin").mkdir(parents=True, exist_ok=True)
    cli = root / "bin" / "ros2"
    cli.write_text(ROS2_CLI)
    cli.chmod(0o755)
    (root / "setup.bash").write_text(SETUP)
    for name in packages:
        (root / "share" / name).mkdir(parents=True, exist_ok=True)
        (root / "share" / name / "package.xml").write_text(f"<package><name>{name}</name></package>\n")
    return root / "bin"
