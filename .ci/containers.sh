#!/usr/bin/env bash
# The OCI engine fogiac's container tests run in: podman with runc, and a ROS base image built
# from Debian's own packages (no image registry is reachable). Idempotent; the image is built
# once per machine and recognised by a stamp holding the digest of this script.
set -euo pipefail

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
if [ "$(cat "$stamp" 2>/dev/null)" = "$want" ] && podman image exists "$IMAGE"; then
    exit 0
fi
echo "containers: building $IMAGE from Debian's packages (about a minute)"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
as_root mmdebstrap --quiet --variant=apt --include="$INCLUDE" \
    --customize-hook='copy-in /usr/local/share/ca-certificates /usr/local/share' \
    --customize-hook='chroot "$1" update-ca-certificates >/dev/null' \
    --customize-hook='chroot "$1" apt-get clean' \
    bookworm "$work/base.tar"
as_root podman import --quiet "$work/base.tar" "$IMAGE" >/dev/null
as_root mkdir -p "$stamp_dir"
echo "$want" | as_root tee "$stamp" >/dev/null
