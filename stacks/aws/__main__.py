"""``pulumi preview`` / ``pulumi up`` entry point for fogiac's aws stacks (see stacks/aws/entry.py)."""

from __future__ import annotations

import sys
from pathlib import Path

try:
    import stacks  # noqa: F401  (installed with fogiac)
except ImportError:  # a checkout: the repository root holds the stacks package
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from stacks.aws.entry import main  # noqa: E402

main(base=Path.cwd())
