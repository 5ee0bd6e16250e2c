"""The benchmark runs where only the libraries are (no typer, no pydantic), and reports per-stage CPU.

The 1-16 core curve is run on a machine that has numpy, OpenCV and GTSAM but not fogiac's CLI
dependencies: here both are made unimportable (a package on the path that raises ImportError), for
the benchmark and every process it starts. Figures are never asserted on (they depend on the load);
what is asserted is that each run reports them, with the cores it got and the stages' CPU seconds.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from tests.conftest import REPO
from tests.workloads.slam.conftest import FEATURES

STAGES = {"read", "extract", "track", "mapping", "loop"}


def _without_cli_packages(root: Path) -> dict[str, str]:
    for name in ("typer", "pydantic"):
        (root / name).mkdir(parents=True)
        (root / name / "__init__.py").write_text(f"raise ImportError('{name} is not installed here')\n")
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), str(REPO)])}


def test_benchmark_runs_without_cli_packages_and_reports_stages(desk: Path, tmp_path: Path) -> None:
    env = _without_cli_packages(tmp_path / "blocked")
    out = tmp_path / "bench.json"
    done = subprocess.run([sys.executable, "-m", "workloads.slam.benchmark", "--sequence", str(desk),
                           "--cores", "1,2", "--runs", "1", "--frames", "40", "--features", str(FEATURES),
                           "--out", str(out)], cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "CPU ms/frame" in done.stdout and "x FPS" in done.stdout
    report = json.loads(out.read_text())
    assert [row["cores"] for row in report["rows"]] == [1, 2]
    for run in report["runs"]:
        assert run["frames"] == 40 and run["tracked_ratio"] >= 0.95
        assert STAGES <= set(run["stage_cpu_s"]) and run["stage_cpu_s"]["extract"] > 0
        assert run["stage_cpu_s"]["track"] > 0 and run["first_map_frame"] is not None
        assert run["cores_used"] > 0 and run["load_before"] >= 0
    assert report["rows"][0]["fps_ratio"] == 1.0


def test_benchmark_bad_cores_is_one_line(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "workloads.slam.benchmark", "--cores", "1,x",
                           "--cache", str(tmp_path)], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1
    assert done.stderr.strip() == "--cores: '1,x' is not a comma-separated list of numbers"
