"""A workload defined only in the tests: ``tally``, declared under ``fogiac.workloads`` by a distribution
of its own (``fogiac_tally``), as a package other than fogiac would. Nothing in fogiac/ names it; the
entry point below is its whole registration (its container recipe module, as fogiac's own workloads')."""

from __future__ import annotations

ENTRY_POINTS = {"fogiac.workloads": {"tally": "tests.plugins.tally.container"}}

# A manifest with one tally node on the local target, for the tests that deploy or check the plugin.
MANIFEST = """\
name: counting
cloud: {provider: local}
nodes:
  - name: counter
    machine: t3.micro
    workload: tally
    topics: {in: [/items], out: [/count]}
"""
