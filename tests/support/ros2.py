"""A stand-in ROS 2 installation for native-runtime tests: no ROS 2 is packaged for this Debian.

Provisioning asks a ROS 2 host (or its ROS image) for ``ros2`` and ``ros2 pkg prefix rmw_zenoh_cpp``;
this folder answers that question as the real CLI does (the prefix of an installed package, else
exit 1), and its ``setup.bash`` puts it on PATH as /opt/ros/<distro>/setup.bash does. A ``launch:``
node's ``colcon build`` and ``ros2 launch PKG FILE`` are stood in too, for a launch file that is a
plain script.
``.ci/containers.sh`` lays it out at /opt/ros/jazzy in the ROS 2 stand-in image. The nodes
themselves are zenoh-ros2-sdk stand-ins, which need nothing from it.
"""

from __future__ import annotations

from pathlib import Path

ROS2_CLI = """#!/bin/bash
# stand-in for ROS 2's CLI: `ros2 pkg prefix NAME`, and `ros2 launch PKG FILE` for a launch file that
# is a plain script, found under share/PKG of a prefix on AMENT_PREFIX_PATH (its setup.bash's, an overlay's)
prefix=$(dirname "$(dirname "$(readlink -f "$0")")")
if [ "$1 $2" = "pkg prefix" ] && [ -f "$prefix/share/$3/package.xml" ]; then echo "$prefix"; exit 0; fi
if [ "$1" = launch ]; then
    IFS=: read -ra prefixes <<< "${AMENT_PREFIX_PATH:-$prefix}"
    for p in "${prefixes[@]}"; do
        found=$(find "$p/share/$2" -name "$3" -print -quit 2>/dev/null)
        if [ -n "$found" ]; then exec "$found"; fi
    done
    echo "Package '$2' not found" >&2; exit 1
fi
echo "Package not found" >&2
exit 1
"""

COLCON = """#!/bin/bash
# stand-in for colcon: `colcon build` installs each src/**/PKG (a package.xml's folder) under install/share/PKG
# and writes install/setup.bash, which puts install/ first on AMENT_PREFIX_PATH
set -e
[ "$1" = build ] || { echo "colcon stand-in: build only" >&2; exit 2; }
find src -name package.xml | while read -r xml; do
    pkg=$(sed -n 's:.*<name>\\(.*\\)</name>.*:\\1:p' "$xml" | head -n 1)
    mkdir -p "install/share/$pkg" && cp -r "$(dirname "$xml")/." "install/share/$pkg/"
done
cat > install/setup.bash <<'SETUP'
_fogiac_ws=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
export AMENT_PREFIX_PATH="$_fogiac_ws${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
SETUP
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
    colcon = root / "bin" / "colcon"
    colcon.write_text(COLCON)
    colcon.chmod(0o755)
    (root / "setup.bash").write_text(SETUP)
    for name in packages:
        (root / "share" / name).mkdir(parents=True, exist_ok=True)
        (root / "share" / name / "package.xml").write_text(f"<package><name>{name}</name></package>\n")
    return root / "bin"
