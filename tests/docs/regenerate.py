"""Rewrite every ``<!-- output (CASE): COMMAND -->`` block of the docs from a real run of its command.

    python -m tests.docs.regenerate          # every page; prints each block it changed
    python -m tests.docs.regenerate --check  # change nothing; exit 1 when a block differs

Run from the repository root with the checkout's environment (``PYTHONPATH=$PWD``). Blocks marked
``checked by`` or ``measured`` are another test's or a measurement's, and are left as they are.
"""

from __future__ import annotations

import argparse
import sys

from tests.docs.blocks import PAGES, blocks, normalise, run_case


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.docs.regenerate", description=__doc__.split("\n")[0])
    parser.add_argument("--check", action="store_true", help="change nothing; exit 1 when a block differs")
    args = parser.parse_args(argv)
    printed: dict[tuple[str, str], str] = {}
    differs = 0
    for page in PAGES:
        text = page.read_text()
        edits = []
        for block in blocks(page):
            if block.kind != "case":
                continue
            key = (block.field("case"), block.field("command"))
            if key not in printed:
                printed[key] = run_case(*key)
            if normalise(block.body) != normalise(printed[key]):
                differs += 1
                print(f"{block.where}: {'differs' if args.check else 'rewritten'} ({key[1]})")
                edits.append((block.start, block.end, printed[key]))
        if edits and not args.check:
            for start, end, body in sorted(edits, reverse=True):
                text = text[:start] + body + text[end:]
            page.write_text(text)
    print(f"{len(printed)} command(s) run; {differs} block(s) {'differ' if args.check else 'rewritten'}",
          file=sys.stderr)
    return 1 if args.check and differs else 0


if __name__ == "__main__":
    sys.exit(main())
