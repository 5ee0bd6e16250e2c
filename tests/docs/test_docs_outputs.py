"""Issue 35, item 25: every command output the docs show is produced by a test. Each block that looks like
output carries a marker naming where it comes from (``tests/docs/blocks.py``); the blocks a case produces are
run here, once per distinct case and command, and must be what the command prints today.

A block that drifted: ``python -m tests.docs.regenerate`` rewrites every case's block from a real run.
"""

from __future__ import annotations

import re
from functools import cache
from pathlib import Path
from types import SimpleNamespace
from typing import cast

import pytest

from tests.docs.blocks import PAGES, REPO, Block, blocks, generated, looks_like_output, normalise, run_case
from workloads.motion_planning.demo import Row, table

ALL = [block for page in PAGES for block in blocks(page)]
CASES = [block for block in ALL if block.kind == "case"]


@cache
def _printed(case: str, command: str) -> str:
    return run_case(case, command)


@pytest.mark.parametrize("block", CASES, ids=[b.where for b in CASES])
def test_each_output_block_is_what_its_command_prints(block: Block) -> None:
    printed = _printed(block.field("case"), block.field("command"))
    assert normalise(block.body) == normalise(printed), f"{block.where}: run python -m tests.docs.regenerate"


def test_every_block_that_looks_like_output_says_where_it_comes_from() -> None:
    unmarked = [b.where for b in ALL if looks_like_output(b) and b.kind is None and not generated(b)]
    assert unmarked == [], ("mark each with <!-- output (CASE): COMMAND -->, <!-- output checked by TEST: "
                            "COMMAND -->, <!-- output measured: COMMAND --> or <!-- not output: WHY --> "
                            "(tests/docs/blocks.py)", unmarked)
    assert CASES, "no block is produced here: the markers' syntax changed?"


def test_a_block_checked_elsewhere_names_a_test_that_reads_its_page() -> None:
    for block in ALL:
        if block.kind != "checked":
            continue
        path, _, name = block.field("test").partition("::")
        source = (REPO / path).read_text()
        assert block.page.name in source, f"{block.where}: {path} does not read {block.page.name}"
        assert not name or re.search(rf"^def {name}\(", source, re.M), f"{block.where}: no test {name} in {path}"


def test_markers_only_name_cases_that_exist_and_blocks_that_are_output() -> None:
    for block in ALL:
        if block.kind is not None:
            assert looks_like_output(block), f"{block.where}: a marked block that is not plain text"
        if block.kind == "case":
            assert (REPO / "tests" / "docs" / "cases" / block.field("case")).is_dir(), block.where


def test_a_measured_demo_table_has_the_shape_the_demo_prints_today() -> None:
    """The benchmarks page's demo table: its numbers are the run's, its lines what ``table`` writes for them."""
    measured = [b for b in ALL if b.kind == "measured" and "workloads.motion_planning.demo" in b.field("measured")]
    assert measured, "the benchmarks page shows no demo table"
    for block in measured:
        lines = block.body.splitlines()
        cores = int(re.search(r"cloud (\d+) cores", lines[0])[1])  # type: ignore[index]
        rows = []
        for line in lines[2:]:
            found = re.fullmatch(r"(\S+) +([\d.]+)s +([\d.]+)s +([\d.]+)s +([\d.]+)s +([\d.]+)x +(\d+)/(\d+) (\d+)/\d+",
                                 line)
            if not found:
                break
            problem, edge, compute, network, total, speedup, edge_ok, runs, cloud_ok = found.groups()
            # the row as recorded: its network time and speedup were computed from unrounded medians
            rows.append(cast(Row, SimpleNamespace(
                problem=problem, edge_s=float(edge), cloud_compute_s=float(compute), network_s=float(network),
                cloud_round_trip_s=float(total), edge_solved=int(edge_ok), cloud_solved=int(cloud_ok),
                runs=int(runs), speedup=float(speedup))))
        assert rows, block.where
        printed = table(rows, cloud_cores=cores).splitlines()
        assert lines[:len(printed)] == printed, block.where
        assert re.fullmatch(r"load average \(1, 5, 15 min\) at the end: [\d.]+ [\d.]+ [\d.]+", lines[len(printed)])
        assert re.fullmatch(r"cores the planners got while planning \(CPU seconds / wall seconds\): "
                            r"robot [\d.]+ of 1, cloud [\d.]+ of \d+", lines[len(printed) + 1])


def test_output_pasted_without_a_marker_is_what_the_guard_flags(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text("\n".join([
        "```text", "fogiac.yaml: valid (1 node, 1 host, target aws)", "```", "",  # plain text
        "```", "first-day-dev: not deployed; nothing to remove", "```", "",  # no language
        "```console", "$ fogiac validate", "fogiac.yaml: valid", "```", "",  # a transcript
        "```sh", "fogiac state unlock lab-dev", "# broke the lock of stack 'lab-dev'", "```", "",  # output as comment
        "```sh", "fogiac validate   # one line per problem", "fogiac plan", "```", "",  # commands: not output
        "```yaml", "name: lab", "```", "",
        "<!-- output (typos): fogiac validate -->", "```text", "fogiac.yaml:9: ...", "```", ""]))
    found = blocks(page)
    assert [looks_like_output(b) for b in found] == [True, True, True, True, False, False, True]
    assert [b.kind for b in found] == [None] * 6 + ["case"]
    assert (found[-1].field("case"), found[-1].field("command")) == ("typos", "fogiac validate")
