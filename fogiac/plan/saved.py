"""Saved plans: ``fogiac plan --out plan.json`` reviewed, then ``fogiac up --plan plan.json``.

A saved plan is only honoured for the exact manifest bytes and fogiac version that made it
(compile is deterministic, so those two fix the plan); anything else is refused in one line
rather than applying something nobody reviewed.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from fogiac import __version__
from fogiac.errors import PlanError
from fogiac.plan.document import FORMAT_VERSION


def manifest_sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def load_saved_plan(path: Path) -> dict[str, Any]:
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise PlanError(f"saved plan {path} does not exist") from None
    except (OSError, ValueError) as err:
        raise PlanError(f"saved plan {path} is unreadable ({err})") from None
    if not isinstance(doc, dict) or doc.get("format_version") != FORMAT_VERSION:
        raise PlanError(f"saved plan {path} is not a fogiac plan document (format_version {FORMAT_VERSION})")
    return doc


def check_saved_plan(path: Path, *, manifest: Path, stack: str, target: str) -> dict[str, Any]:
    """The saved plan at ``path`` if it still describes ``manifest`` for this fogiac; else PlanError."""
    doc = load_saved_plan(path)
    recorded = (doc.get("manifest") or {}).get("sha256")
    actual = manifest_sha256(manifest)
    if recorded != actual:
        raise PlanError(f"saved plan {path} was made from another version of {manifest} "
                        f"(sha256 {str(recorded)[:12]} there, {actual[:12]} now); run `fogiac plan --out` again")
    if doc.get("fogiac_version") != __version__:
        raise PlanError(f"saved plan {path} was made by fogiac {doc.get('fogiac_version')}, this is {__version__}; "
                        f"run `fogiac plan --out` again")
    if doc.get("stack") != stack or doc.get("target") != target:
        raise PlanError(f"saved plan {path} is for stack {doc.get('stack')} on {doc.get('target')}, "
                        f"not {stack} on {target}; pass the same --env and --target")
    return doc
