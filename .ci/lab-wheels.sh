#!/usr/bin/env bash
# A lab's local package mirror for the namespace hosts of the provisioning tests: they have no
# route to PyPI, and this machine's mirror (/opt/pypi) lacks some workload requirements (ompl,
# python-fcl, pycollada, eclipse-zenoh). Downloads fogiac's, the middlewares' and the workloads'
# requirements but torch (its CPU wheel is in /opt/wheels; a plain download pulls GBs of CUDA) with
# their dependencies, once per list.
set -euo pipefail
cd "$(dirname "$0")/.."

as_root() { if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi; }

dest=/var/cache/fogiac-ci/lab-wheels
mapfile -t reqs < <(.venv/bin/python -c '
from fogiac.net import middleware
from fogiac.provision.venv import requirements
hosts = tuple(r for name in sorted(middleware.BUILTIN) for r in middleware.get(name).host_requirements)
print("\n".join(r for r in requirements(["grasp_planning", "motion_planning"], fogiac=True, middleware=hosts)
                if not r.startswith("torch")))')
want=$(printf '%s\n' "${reqs[@]}" | sha256sum | cut -d' ' -f1)
if [ "$(cat "$dest/.stamp" 2>/dev/null)" = "$want" ]; then
    exit 0
fi
echo "lab-wheels: downloading ${reqs[*]} into $dest"
as_root mkdir -p "$dest"
as_root .venv/bin/pip download -q --only-binary=:all: -d "$dest" "${reqs[@]}" 2> >(grep -v "is ignored: it is neither" >&2)
as_root chmod -R a+rX "$dest"
echo "$want" | as_root tee "$dest/.stamp" >/dev/null
