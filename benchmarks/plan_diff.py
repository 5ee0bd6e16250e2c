"""Benchmark: ``fogiac plan HEAD --against BASE`` of a 100-node manifest against one ``plan`` of it.

Goal (issue 16): the two-manifest diff under 3x one plan. The diff compiles and declares both
manifests (two offline plans in one process) and compares them; each figure is the best of N
runs of a fresh interpreter, printed beside ``python -c pass`` measured in the same run.

    .venv/bin/python benchmarks/plan_diff.py [--runs 5]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from plan import best, manifest  # noqa: E402  (benchmarks/plan.py: the same 100-node manifest)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    runs = parser.parse_args().runs
    py = sys.executable
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, FOGIAC_STATE_DIR=str(Path(tmp) / "state"))
        base, head = Path(tmp) / "base.yaml", Path(tmp) / "head.yaml"
        base.write_text(manifest(100))
        one_change = ("name: node7\n    machine: t3.medium", "name: node7\n    machine: t3.large")
        head.write_text(manifest(100).replace(*one_change))
        baseline = best([py, "-c", "pass"], runs=runs, env=env)
        one = best([py, "-m", "fogiac", "plan", str(head)], runs=runs, env=env)
        two = best([py, "-m", "fogiac", "plan", str(head), "--against", str(base)], runs=runs, env=env)
    print(f"python -c pass:                       {baseline[0]:.3f} s wall, {baseline[1]:.3f} s CPU")
    print(f"plan, 100 nodes:                      {one[0]:.3f} s wall, {one[1]:.3f} s CPU")
    print(f"plan --against, 100 nodes vs 100:     {two[0]:.3f} s wall, {two[1]:.3f} s CPU")
    print(f"ratio diff/plan: {two[0] / one[0]:.2f}x wall, {two[1] / one[1]:.2f}x CPU (goal: under 3x)")


if __name__ == "__main__":
    main()
