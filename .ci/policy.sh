#!/usr/bin/env bash
# The policy gate: every example's offline plan, exported as Terraform plan JSON, scanned by
# checkov (pinned in .ci/checkov.sh, in its own venv). Fails on any failed check that the exported
# document does not declare by design (its "fogiac.by_design" list, each with a reason;
# docs/guides/pull-requests.md, "Checks that fail by design", gives the same reasons). Needs no
# credentials and no Pulumi CLI.
#
# One checkov run scans every plan (its start-up, about 20 s of loading checks, dominated six runs),
# and each file's failures are then judged against that file's own by-design list: the same verdict
# as one run per file with --skip-check, never a check skipped for one example because another
# declares it.
set -euo pipefail
cd "$(dirname "$0")/.."
bash .ci/checkov.sh >/dev/null
python="${FOGIAC_PYTHON:-.venv/bin/python}"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
files=()
for manifest in examples/*.yaml; do
    plan="$out/$(basename "$manifest" .yaml).json"
    "$python" -m fogiac plan "$manifest" --format terraform-json > "$plan"
    files+=(-f "$plan")
done
# checkov exits 1 when any check fails, by design or not: the verdict below decides.
.checkov-venv/bin/checkov "${files[@]}" --framework terraform_plan --skip-download --compact \
    --output json > "$out/checkov.json" 2> "$out/checkov.err" || true
exec "$python" - "$out" <<'PY'
import json
import sys
from collections import Counter
from pathlib import Path

out = Path(sys.argv[1])
try:
    report = json.loads((out / "checkov.json").read_text())
except ValueError:
    sys.exit("policy: checkov gave no JSON report:\n" + (out / "checkov.err").read_text()[-3000:])
results = report["results"]
name = lambda check: Path(check["file_path"]).stem  # noqa: E731  (checkov names the file "/<name>.json")
passed = Counter(name(c) for c in results.get("passed_checks", []))
status = 0
for plan in sorted(out.glob("*.json")):
    if plan.name == "checkov.json":
        continue
    by_design = {d["check"] for d in json.loads(plan.read_text())["fogiac"]["by_design"]}
    failed = [c for c in results.get("failed_checks", []) if name(c) == plan.stem]
    unexpected = [c for c in failed if c["check_id"] not in by_design]
    if unexpected:
        status = 1
        print(f"policy: {plan.stem}: FAILED (by design, skipped: {','.join(sorted(by_design))})")
        for c in unexpected:
            print(f"  {c['check_id']}: {c['check_name']}\n    {c['resource']}")
    else:
        print(f"policy: {plan.stem}: Passed checks: {passed[plan.stem]}, Failed checks: 0, "
              f"Skipped by design: {len(failed)}")
sys.exit(status)
PY
