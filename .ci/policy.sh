#!/usr/bin/env bash
# The policy gate: every example's offline plan, exported as Terraform plan JSON, scanned by
# checkov (pinned in .ci/checkov.sh, in its own venv). Fails on any failed check that the exported
# document does not declare by design (its "fogiac.by_design" list, each with a reason;
# docs/guides/pull-requests.md, "Checks that fail by design", gives the same reasons). Needs no
# credentials and no Pulumi CLI.
set -euo pipefail
cd "$(dirname "$0")/.."
bash .ci/checkov.sh >/dev/null
python="${FOGIAC_PYTHON:-.venv/bin/python}"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
status=0
for manifest in examples/*.yaml; do
    name="$(basename "$manifest" .yaml)"
    plan="$out/$name.json"
    "$python" -m fogiac plan "$manifest" --format terraform-json > "$plan"
    skips="$("$python" -c 'import json,sys; print(",".join(d["check"] for d in json.load(open(sys.argv[1]))["fogiac"]["by_design"]))' "$plan")"
    if .checkov-venv/bin/checkov -f "$plan" --framework terraform_plan --skip-check "$skips" \
        --compact --quiet --output cli > "$out/$name.txt" 2>&1; then
        echo "policy: $name: $(grep -m1 'Passed checks' "$out/$name.txt" || echo 'no checks ran')"
    else
        status=1
        echo "policy: $name: FAILED (by design, skipped: $skips)"
        cat "$out/$name.txt"
    fi
done
exit "$status"
