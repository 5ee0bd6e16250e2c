#!/usr/bin/env bash
# A lab's local package mirror for the namespace hosts of the provisioning tests: they have no
# route to PyPI, and this machine's mirror (/opt/pypi) lacks some workload requirements (ompl,
# python-fcl, pycollada, eclipse-zenoh). Downloads fogiac's, the middlewares' and the workloads'
# requirements with their dependencies, once per list; torch's CPU wheel comes from /opt/wheels (a plain download pulls GBs of CUDA). The
# folder is complete on its own: the container tests serve it over HTTP as the lab's only index.
set -euo pipefail
cd "$(dirname "$0")/.."

as_root() { if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi; }

dest=/var/cache/fogiac-ci/lab-wheels
mapfile -t reqs < <(.venv/bin/python -c '
from fogiac.net import middleware
from fogiac.provision.venv import requirements
hosts = tuple(r for name in middleware.names() for r in middleware.get(name).host_requirements)
print("\n".join(requirements(["grasp_planning", "motion_planning"], fogiac=True, middleware=hosts)))')
want=$(printf '%s\n' "${reqs[@]}" | sha256sum | cut -d' ' -f1)
if [ "$(cat "$dest/.stamp" 2>/dev/null)" = "$want" ]; then
    exit 0
fi
echo "lab-wheels: downloading ${reqs[*]} into $dest"
as_root mkdir -p "$dest"
as_root .venv/bin/pip download -q --only-binary=:all: --find-links /opt/wheels -d "$dest" "${reqs[@]}" 2> >(grep -v "is ignored: it is neither" >&2)
as_root chmod -R a+rX "$dest"
echo "$want" | as_root tee "$dest/.stamp" >/dev/null
