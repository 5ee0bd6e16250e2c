"""Provisioning benchmark on real SSH hosts (network namespaces with sshd; needs root and ROS).

Figures, each a ratio against a baseline measured in the same run:
  1. wall time provisioning N hosts vs 1 host, from scratch          (goal <= 1.5x)
  2. a no-op re-run vs the first run over N hosts                     (goal <= 10%)
  3. workspace bytes sent re-pushing after one changed file vs first  (goal <= 5%)

    sudo .venv/bin/python benchmarks/provision.py --hosts 8 --files 40 [--mesh-kb 256]
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from fogiac.manifest.schema import load_manifest  # noqa: E402
from fogiac.plan.compile import compile_plan  # noqa: E402
from fogiac.provision import ProvisionReport, provision, teardown  # noqa: E402
from fogiac.targets.hosts.target import HOSTS  # noqa: E402
from tests.provision.conftest import hosts_manifest, make_workspace, ros_skip_reason  # noqa: E402
from tests.provision.sshlab import LabHost, lab_skip_reason, ssh_lab  # noqa: E402


def _cpu_busy() -> tuple[float, float]:
    """(busy, total) jiffies of all CPUs, from /proc/stat."""
    fields = [float(x) for x in Path("/proc/stat").read_text().splitlines()[0].split()[1:]]
    idle = fields[3] + fields[4]
    return sum(fields) - idle, sum(fields)


def _slowest_steps(report: ProvisionReport) -> str:
    """Each step's slowest host, to show where the time goes."""
    slowest: dict[str, float] = {}
    for host in report.hosts:
        for step in host.steps:
            slowest[step.name] = max(slowest.get(step.name, 0.0), step.seconds)
    return ", ".join(f"{name} {seconds:.1f}s" for name, seconds in slowest.items())


def _workspace_bytes(report: ProvisionReport) -> int:
    total = 0
    for host in report.hosts:
        for step in host.steps:
            found = re.match(r"pushed \d+ file\(s\), (\d+) bytes", step.detail)
            if step.name == "workspace" and found:
                total += int(found.group(1))
    return total


class Bench:
    def __init__(self, root: Path, hosts: list[LabHost], key: Path, files: int) -> None:
        self.root, self.hosts, self.key = root, hosts, key
        self.state = root / "state"
        self.state.mkdir()
        self.workspace = make_workspace(root / "ws", extra_files=files)

    def _plan_access(self, hosts: list[LabHost]):  # type: ignore[no-untyped-def]
        manifest = hosts_manifest(self.root / "fogiac.yaml", hosts=[(h.name, h.address) for h in hosts],
                                  key=self.key, workspace=self.workspace, name="bench")
        plan = compile_plan(load_manifest(manifest))
        by_name = {h.name: h for h in hosts}
        access = {n: replace(a, base_dir=str(by_name[n].base_dir), ship_code=False)  # type: ignore[type-var]
                  for n, a in HOSTS.access(plan, state_dir=self.state, python=sys.executable).items()}
        return plan, access

    def run(self, hosts: list[LabHost]) -> tuple[float, ProvisionReport]:
        plan, access = self._plan_access(hosts)
        busy0, total0 = _cpu_busy()
        started = time.monotonic()
        report = provision(plan, hosts=access, state_dir=self.state, health_timeout=120)
        elapsed = time.monotonic() - started
        busy1, total1 = _cpu_busy()
        self.busy = (busy1 - busy0) / max(1.0, total1 - total0)
        if not report.ok:
            raise SystemExit("provisioning failed: " + "; ".join(h.error or "" for h in report.failed))
        return elapsed, report

    def down(self, hosts: list[LabHost]) -> None:
        plan, access = self._plan_access(hosts)
        teardown(plan, hosts=access, state_dir=self.state)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hosts", type=int, default=8)
    parser.add_argument("--files", type=int, default=40, help="extra config files in the workspace")
    parser.add_argument("--mesh-kb", type=int, default=0,
                        help="add a binary mesh of this size (incompressible, like an STL) to the workspace")
    args = parser.parse_args()
    reason = lab_skip_reason() or ros_skip_reason()
    if reason:
        print(f"skipped: {reason}")
        return 0
    with tempfile.TemporaryDirectory(prefix="fogiac-bench-") as tmp, ssh_lab(Path(tmp), args.hosts) as (hosts, key):
        bench = Bench(Path(tmp), hosts, key, args.files)
        if args.mesh_kb:
            meshes = bench.workspace / "src" / "fogtest" / "meshes"
            meshes.mkdir()
            (meshes / "gripper.stl").write_bytes(os.urandom(args.mesh_kb * 1024))
        one, single = bench.run(hosts[:1])
        busy_one = bench.busy
        bench.down(hosts[:1])
        many, first = bench.run(hosts)
        busy_many = bench.busy
        noop, again = bench.run(hosts)
        changed = bench.workspace / "src" / "fogtest" / "config" / "params_007.yaml"
        changed.write_text(changed.read_text() + "tuned: true\n")
        _, repush = bench.run(hosts)
        bench.down(hosts)
    first_bytes, repush_bytes = _workspace_bytes(first), _workspace_bytes(repush)
    mesh = f" and a {args.mesh_kb} KiB binary mesh" if args.mesh_kb else ""
    print(f"workspace: the fogtest package with {args.files} extra config files{mesh}")
    print(f"provision 1 host:            {one:6.2f} s   ({_slowest_steps(single)})")
    print(f"provision {args.hosts} hosts:           {many:6.2f} s   ratio {many / one:.2f}x   (goal <= 1.5x)   "
          f"({_slowest_steps(first)})")
    print(f"CPU busy (whole machine, {os.cpu_count()} CPUs shared by every host's roscore and nodes): "
          f"{busy_one:.0%} during 1 host, {busy_many:.0%} during {args.hosts} hosts; load average now "
          f"{os.getloadavg()[0]:.1f}")
    print(f"no-op re-run ({again.summary()}): {noop:6.2f} s   ratio {noop / many:.1%}   (goal <= 10%)   "
          f"({_slowest_steps(again)})")
    print(f"workspace bytes, first push: {first_bytes} B over {args.hosts} hosts; after one changed file: "
          f"{repush_bytes} B   ratio {repush_bytes / first_bytes:.1%}   (goal <= 5%)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
