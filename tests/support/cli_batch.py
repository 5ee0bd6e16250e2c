"""Run several ``fogiac`` commands one after another in one fresh Python process (``python -m
tests.support.cli_batch``): a JSON list of ``{"argv": [...], "env": {NAME: value or null}}`` on stdin, a
JSON list of ``[exit status, what it printed]`` on stdout.

Why: the ``kill -9`` walks (tests/targets/aws/test_shared_state_kill.py) check what each kill left with up to
five read-only commands of another operator (``state show``, ``status``, ``state unlock`` per store); as five
processes each paid Python's start, fogiac's imports and (S3) a boto3 client, most of the walk's time. One
process per kill is still an operator's fresh fogiac: nothing changes the store between its commands, so a
store the first command opened (and the stack files it pulled) is what the next would have read.
"""

from __future__ import annotations

import json
import sys
import traceback


def main() -> None:
    from typer.testing import CliRunner

    from fogiac.cli import app

    out = []
    for call in json.load(sys.stdin):
        result = CliRunner().invoke(app, call["argv"], env=call.get("env") or {})
        text = result.output
        if result.exception is not None and not isinstance(result.exception, SystemExit):  # as the CLI would show it
            text += "".join(traceback.format_exception(result.exception))
        out.append([result.exit_code, text])
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
