"""The benchmark's ``--curve`` (run by the lead on a many-core device) needs only numpy, ompl, python-fcl and
trimesh beside the source tree: no fogiac install, no pydantic, typer or yaml."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from tests.workloads.motion_planning.mp_support import REPO

# every finder answers "no such module" for anything but the standard library, the four packages the
# device has, and the source tree: as if nothing else were installed
ONLY = '''
import sys
ALLOWED = {"numpy", "ompl", "fcl", "trimesh", "fogiac", "workloads", "benchmarks", "sitecustomize"}


class _Only:
    def __init__(self, inner):
        self.inner = inner

    def find_spec(self, name, path=None, target=None):
        top = name.split(".")[0]
        if not (top in sys.stdlib_module_names or top in ALLOWED or top.startswith("_")):
            return None
        return self.inner.find_spec(name, path, target)

    def __getattr__(self, attr):
        return getattr(self.inner, attr)


sys.meta_path[:] = [_Only(f) if hasattr(f, "find_spec") else f for f in sys.meta_path]
'''


def _env(tmp_path: Path) -> dict[str, str]:
    (tmp_path / "sitecustomize.py").write_text(ONLY, encoding="utf-8")
    return {"PYTHONPATH": f"{tmp_path}:{REPO}", "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}


def test_the_curve_runs_with_only_the_devices_packages(tmp_path: Path) -> None:
    env = _env(tmp_path)
    probe = subprocess.run([sys.executable, "-c", "import pydantic"], env=env, capture_output=True, text=True)
    assert "No module named 'pydantic'" in probe.stderr  # the stand-in for the device's bare Python holds
    done = subprocess.run([sys.executable, "benchmarks/planner_pairs.py", "--curve", "1,2", "--runs", "1", "cubicles"],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    rows = [line for line in done.stdout.splitlines() if line.strip().startswith("cubicles") and "workers:" in line]
    assert [row.split()[1] for row in rows] == ["1", "2"], done.stdout
    for row in rows:
        for figure in ("search", "solve", "work per worker", "serial share", "cores used", "solved 1/1"):
            assert figure in row, row
    assert "load average at start" in done.stdout and "projection" in done.stdout
