#!/usr/bin/env bash
# Create (or reuse) the LocalStack venv at .localstack-venv/ in the repo root.
# Idempotent: a venv whose stamp matches the pins below is left alone.
# Pins (../shared/TESTING.md): 4.13.1 is the last LocalStack that runs on Python 3.11; newer
# cbor2 / pyOpenSSL break its imports.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.localstack-venv"
python="${LOCALSTACK_PYTHON:-/usr/bin/python3}"
command -v "$python" >/dev/null 2>&1 || python=python3
pins=(
  "localstack-core[runtime]==4.13.1"
  "cbor2==5.6.5"
  "pyopenssl==25.1.0"
  "cryptography>=45.0.1"
  "service_identity"
)
stamp="$venv/.fogiac-pins"
want="$(printf '%s\n' "${pins[@]}")"
if [[ -x "$venv/bin/python" && -f "$stamp" && "$(cat "$stamp")" == "$want" ]]; then
  echo "localstack venv ready: $venv"
  exit 0
fi
"$python" -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --upgrade pip
"$venv/bin/python" -m pip install --quiet --no-compile "${pins[@]}"
"$venv/bin/python" -c "import localstack.runtime.main"
printf '%s\n' "${pins[@]}" > "$stamp"
echo "localstack venv ready: $venv"
