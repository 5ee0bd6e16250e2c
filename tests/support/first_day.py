"""The wheels the getting-started page's install needs, kept once per list (issue 35's fresh-venv test).

The test installs from them with no network at all. ``.ci/test`` starts ``python -m tests.support.first_day``
in the background before the tests, so the download overlaps the first of them; the test then finds the
wheelhouse complete, or waits on its lock while the download finishes. Run on its own it downloads the
same way the test would.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import re
import shlex
import subprocess
import sys
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
GETTING_STARTED = REPO / "docs" / "getting-started.md"
WHEELS = Path(os.environ.get("FOGIAC_FIRST_DAY_WHEELS", "/var/cache/fogiac-ci/first-day-wheels"))
LAB_WHEELS = Path("/var/cache/fogiac-ci/lab-wheels")  # .ci/lab-wheels.sh: fogiac's and the workloads' wheels
EXTRAS = ("aws", "ssh")  # what the page installs: not ``all``


def install_lines() -> list[str]:
    """The page's install block (between its ``install:begin`` and ``install:end`` markers)."""
    text = GETTING_STARTED.read_text()
    block = text[text.index("<!-- install:begin -->"):text.index("<!-- install:end -->")]
    return [line for line in re.findall(r"^```bash\n(.*?)^```", block, flags=re.M | re.S)[0].splitlines() if line]


def declared(extras: tuple[str, ...]) -> list[str]:
    """fogiac's requirements with ``extras``, from pyproject.toml (no build of fogiac needed to list them)."""
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    return [*project["dependencies"], *(r for extra in extras for r in project["optional-dependencies"][extra])]


def wanted() -> list[str]:
    """Everything the page's install lines ask pip for: fogiac's requirements, then the planner's line."""
    planner = shlex.split(install_lines()[3])[2:]
    return [*declared(EXTRAS), *planner, "setuptools>=68", "wheel"]


def wheelhouse(wanted: list[str]) -> Path:
    """Every wheel in ``wanted``, downloaded once (PyPI, and the lab's wheels already here) and kept by the
    list's digest. One download at a time: a second caller waits on the lock, then finds the stamp."""
    digest = hashlib.sha256("\n".join(wanted).encode()).hexdigest()
    WHEELS.mkdir(parents=True, exist_ok=True)
    stamp = WHEELS / ".stamp"
    with open(WHEELS / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if stamp.is_file() and stamp.read_text() == digest:
            return WHEELS
        links = ["--find-links", str(LAB_WHEELS)] if LAB_WHEELS.is_dir() else []
        subprocess.run([sys.executable, "-m", "pip", "download", "-q", "--only-binary=:all:", "-d", str(WHEELS),
                        *links, *wanted], check=True, timeout=1500)
        stamp.write_text(digest)
    return WHEELS


if __name__ == "__main__":
    print(f"first-day wheels: {wheelhouse(wanted())}")
