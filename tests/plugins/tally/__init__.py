"""A workload defined only in the tests: ``tally``, declared under ``fogiac.workloads`` by a distribution
of its own (``fogiac_tally``), as a package other than fogiac would. Nothing in fogiac/ names it; the
entry point below is its whole registration (its container recipe module, as fogiac's own workloads')."""

from __future__ import annotations

ENTRY_POINTS = {"fogiac.workloads": {"tally": "tests.plugins.tally.container"}}
