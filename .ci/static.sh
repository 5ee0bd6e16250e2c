#!/usr/bin/env bash
# The slower static checks: mypy, the docs build (mkdocs --strict) and the policy gate (checkov on every
# example's plan). .ci/test runs this beside the tests, at the lowest CPU priority; run alone, it is the
# same checks at once. Exits non-zero when any check failed, after printing that check's output.
set -euo pipefail
cd "$(dirname "$0")/.."
checks=$(mktemp -d)
trap 'rm -rf "$checks"' EXIT
# Each is one process on one core; mypy is the longest (about two minutes on a fresh clone).
bash .ci/policy.sh > "$checks/policy" 2>&1 &
policy=$!
.venv/bin/mypy > "$checks/mypy" 2>&1 &
mypy=$!
status=0
echo "docs: mkdocs build --strict (a broken link or a page missing from the nav fails)"
if ! NO_MKDOCS_2_WARNING=1 .venv/bin/mkdocs build --strict --site-dir "$checks/site" > "$checks/docs" 2>&1; then
    grep -v '^INFO' "$checks/docs"; status=1
fi
echo "mypy: fogiac, stacks, workloads"
if wait "$mypy"; then tail -n 1 "$checks/mypy"; else cat "$checks/mypy"; status=1; fi
echo "policy: checkov on every example's plan"
if wait "$policy"; then grep '^policy:' "$checks/policy"; else cat "$checks/policy"; status=1; fi
exit "$status"
