#!/usr/bin/env bash
# Create (or reuse) the checkov venv at .checkov-venv/ in the repo root, apart from fogiac's own
# venv so checkov's many pinned dependencies never meet fogiac's. Idempotent: a venv whose stamp
# matches the pin below is left alone. 3.3.30 is the release the by-design skips were checked with.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.checkov-venv"
python="${CHECKOV_PYTHON:-/usr/bin/python3}"
command -v "$python" >/dev/null 2>&1 || python=python3
pins=("checkov==3.3.30")
stamp="$venv/.fogiac-pins"
want="$(printf '%s\n' "${pins[@]}")"
if [[ -x "$venv/bin/checkov" && -f "$stamp" && "$(cat "$stamp")" == "$want" ]]; then
  echo "checkov venv ready: $venv"
  exit 0
fi
"$python" -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --upgrade pip
"$venv/bin/python" -m pip install --quiet --no-compile "${pins[@]}"
"$venv/bin/checkov" --version
printf '%s\n' "${pins[@]}" > "$stamp"
echo "checkov venv ready: $venv"
