#!/usr/bin/env bash
# The OCI engine fogiac's container tests run in: podman with runc, and a ROS base image built
# from Debian's own packages (no image registry is reachable). Idempotent; the image is built
# once per machine and recognised by a stamp holding the digest of this script.
set -euo pipefail
cd "$(dirname "$0")/.."

as_root() { if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi; }

# The defaults ask for rlimits above these machines' hard limits (setrlimit fails), and crun
# cannot run on their hybrid cgroup setup: runc and modest ulimits work.
conf=/etc/containers/containers.conf
want_conf='[containers]
default_ulimits = ["nofile=1024:1024", "nproc=1024:1024"]

[engine]
runtime = "runc"'
if [ ! -e "$conf" ]; then
    as_root mkdir -p /etc/containers
    printf '%s\n' "$want_conf" | as_root tee "$conf" >/dev/null
    echo "containers: wrote $conf"
elif ! grep -q 'runtime *= *"runc"' "$conf" || ! grep -q 'default_ulimits' "$conf"; then
    echo "containers: $conf exists and differs from what the tests need; left as it is. Wanted:" >&2
    printf '%s\n' "$want_conf" >&2
fi

# The test base image answers to the official name, so recipes that say FROM ros:noetic-ros-core
# build here as they do against Docker Hub. The host's extra CA certificates go in too, so pip
# inside a build trusts what pip on the host trusts.
IMAGE=docker.io/library/ros:noetic-ros-core
INCLUDE=ros-core,python3-rospy,python3-std-msgs,python3-sensor-msgs,python3-geometry-msgs,python3-venv,python3-pip,ca-certificates,catkin,cmake,g++,make
stamp_dir=/var/lib/fogiac-ci
stamp="$stamp_dir/ros-base.stamp"
want=$(printf '%s\n%s\n' "$IMAGE" "$INCLUDE" | sha256sum | cut -d' ' -f1)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ] || ! podman image exists "$IMAGE"; then
    echo "containers: building $IMAGE from Debian's packages (about a minute)"
    as_root mmdebstrap --quiet --variant=apt --include="$INCLUDE" \
        --customize-hook='copy-in /usr/local/share/ca-certificates /usr/local/share' \
        --customize-hook='chroot "$1" update-ca-certificates >/dev/null' \
        --customize-hook='chroot "$1" apt-get clean' \
        bookworm "$work/base.tar"
    as_root podman import --quiet "$work/base.tar" "$IMAGE" >/dev/null
    as_root mkdir -p "$stamp_dir"
    echo "$want" | as_root tee "$stamp" >/dev/null
fi

# No ROS 2 image or package can be had here: the ROS 2 stand-in answers to the name fogiac runs
# ROS 2 nodes in (images.base_image), and is the base above plus zenoh-ros2-sdk (rmw_zenoh's key
# expressions, and its ZENOH_CONFIG_OVERRIDE / ZENOH_SESSION_CONFIG_URI), at the ros2 extra's pins,
# and at /opt/ros/jazzy the stand-in ROS 2 of tests/support/ros2.py (`ros2 pkg prefix rmw_zenoh_cpp`
# answers, as in an image that has rmw_zenoh_cpp).
# Its wheels come through the host's pip (its cache or mirror); the build itself has no network.
# There is no git in it: the SDK's message fetcher stays quiet (nodes pass their definitions).
IMAGE2=docker.io/library/ros:jazzy-ros-core
mapfile -t pins < <(.venv/bin/python -c '
import tomllib
print("\n".join(tomllib.load(open("pyproject.toml", "rb"))["project"]["optional-dependencies"]["ros2"]))')
dockerfile="FROM $IMAGE
COPY ros /opt/ros/jazzy
COPY wheels /tmp/wheels
RUN python3 -m pip install --quiet --root-user-action=ignore --break-system-packages --no-index --find-links /tmp/wheels ${pins[*]} && rm -rf /tmp/wheels
ENV ROS_DISTRO=jazzy GIT_PYTHON_REFRESH=quiet"
stamp2="$stamp_dir/ros2-standin.stamp"
want2=$(printf '%s\n%s\n%s\n%s\n' "$IMAGE2" "$want" "$dockerfile" "$(sha256sum tests/support/ros2.py)" \
    | sha256sum | cut -d' ' -f1)
if [ "$(cat "$stamp2" 2>/dev/null)" = "$want2" ] && podman image exists "$IMAGE2"; then
    exit 0
fi
echo "containers: building the ROS 2 stand-in $IMAGE2 (zenoh-ros2-sdk over $IMAGE)"
mkdir -p "$work/ros2/wheels"
.venv/bin/pip download -q --only-binary=:all: -d "$work/ros2/wheels" "${pins[@]}" 2> >(grep -v "is ignored: it is neither" >&2)
.venv/bin/python -c 'import sys; from pathlib import Path; from tests.support.ros2 import standin_ros2
standin_ros2(Path(sys.argv[1]))' "$work/ros2/ros"
printf '%s\n' "$dockerfile" > "$work/ros2/Dockerfile"
old=$(podman image inspect --format '{{.Id}}' "$IMAGE2" 2>/dev/null || true)
as_root podman build --quiet --pull=never --network none -t "$IMAGE2" "$work/ros2" >/dev/null
new=$(podman image inspect --format '{{.Id}}' "$IMAGE2")
if [ -n "$old" ] && [ "$old" != "$new" ]; then as_root podman rmi "$old" >/dev/null 2>&1 || true; fi  # the one it replaced
echo "$want2" | as_root tee "$stamp2" >/dev/null
