"""Saved plans: ``fogiac plan --out plan.json`` reviewed, then ``fogiac up --plan plan.json``.

``up --plan`` applies exactly what was reviewed, or nothing. So a saved plan binds every input that
decides what ``up`` would do, and ``up`` refuses it in one line naming the first one that changed:

- the document itself: ``plan --out`` stores a digest over its canonical content (``saved.sha256``), so
  a plan file edited by hand (hosts emptied, a resource dropped) is refused before anything in it is read;
- fogiac's version, the stack, target and environment, and the manifest's bytes (compile is
  deterministic, so with those the compiled plan is fixed);
- the machine catalogue machines were chosen and priced from (a refreshed one changes both);
- every file ``up`` pushes to the hosts (workspaces, env scripts, requirements files, build contexts),
  by the content digests the document lists (:mod:`fogiac.plan.pushed`);
- the stack record it was planned against (its lineage and serial, :mod:`fogiac.state`): anyone's
  ``up`` or ``down`` since then moves the record on, and what was reviewed was a change to what ran then.

``up`` checks these before it starts, and again under the stack's lock, as the document it is about to
apply is shown (:func:`check_applies`): the record once more (nobody applied in between) and the plan's
digest, which covers every resource and setting the reviewers saw. The digest detects edits, not
forgery: who can write the plan file could recompute it, so keep the file where only CI writes it.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from fogiac import __version__
from fogiac.errors import PlanError
from fogiac.manifest.clouds import catalogue_digest
from fogiac.plan.document import FORMAT_VERSION
from fogiac.plan.model import Plan
from fogiac.plan.pushed import pushed
from fogiac.plan.review import visible
from fogiac.state import StackState

SAVED = "saved"  # the document's section that binds it: record, catalogue, and its own digest
AGAIN = "run `fogiac plan --out` again"
_WHAT = {"workspace": "workspace", "env_script": "env script", "requirements": "requirements file",
         "build": "build context"}


def manifest_sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def record_version(stack: str) -> dict[str, Any] | None:
    """The stack record's lineage and serial as the store holds it now; None: no record (never deployed)."""
    document = StackState(stack).snapshot().document
    if document is None:
        return None
    return {"lineage": document.get("lineage"), "serial": document.get("serial")}


def document_sha256(doc: Mapping[str, Any]) -> str:
    """The digest of a saved plan's canonical content: every key, sorted, less the digest itself."""
    body = {**doc, SAVED: {k: v for k, v in dict(doc.get(SAVED) or {}).items() if k != "sha256"}}
    return hashlib.sha256(json.dumps(body, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def bind(doc: Mapping[str, Any], *, plan: Plan) -> dict[str, Any]:
    """``doc`` as ``plan --out`` saves it: with the record it was planned against, the catalogue's digest,
    and a digest of the whole."""
    saved = {"record": record_version(plan.stack), "catalogue_sha256": catalogue_digest(plan.target)}
    bound = {**doc, SAVED: saved}
    return {**bound, SAVED: {**saved, "sha256": document_sha256(bound)}}


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


def check_saved_plan(path: Path, *, manifest: Path, stack: str, target: str,
                     plan: Plan | None = None) -> dict[str, Any]:
    """The saved plan at ``path`` if it still describes what ``up`` would apply; else PlanError naming the
    first thing that changed. Without ``plan``, only the manifest, fogiac's version, stack and target are
    compared (what a document that ``plan --out`` did not bind can show)."""
    doc = load_saved_plan(path)
    saved = doc.get(SAVED)
    if plan is not None and not isinstance(saved, dict):
        raise PlanError(f"saved plan {path} binds nothing up can check (it has no `{SAVED}` section: "
                        f"`fogiac plan --out` did not write it); {AGAIN}")
    if isinstance(saved, dict) and saved.get("sha256") != document_sha256(doc):
        raise PlanError(f"saved plan {path} was edited after `fogiac plan --out` wrote it (its content no longer "
                        f"matches its digest); {AGAIN}")
    if doc.get("fogiac_version") != __version__:
        raise PlanError(f"saved plan {path} was made by fogiac {_said(doc.get('fogiac_version'))}, "
                        f"this is {__version__}; {AGAIN}")
    if doc.get("stack") != stack or doc.get("target") != target:
        raise PlanError(f"saved plan {path} is for stack {_said(doc.get('stack'))} on {_said(doc.get('target'))}, "
                        f"not {stack} on {target}; pass the same --env and --target")
    if plan is not None and doc.get("environment") != plan.environment:
        raise PlanError(f"saved plan {path} is for environment {_said(doc.get('environment'))}, "
                        f"not {plan.environment}; pass the same --env")
    recorded = (doc.get("manifest") or {}).get("sha256")
    actual = manifest_sha256(manifest)
    if recorded != actual:
        raise PlanError(f"saved plan {path} was made from another version of {manifest} "
                        f"(sha256 {_short(recorded)} there, {actual[:12]} now); {AGAIN}")
    if plan is None:
        return doc
    assert isinstance(saved, dict)
    catalogue = catalogue_digest(plan.target)
    if saved.get("catalogue_sha256") != catalogue:
        raise PlanError(f"saved plan {path} was made with another machine catalogue "
                        f"(sha256 {_short(saved.get('catalogue_sha256'))} there, {_short(catalogue)} now); {AGAIN}")
    _same_pushed(path, doc.get("pushed"), pushed(plan))
    _same_record(path, saved.get("record"), stack)
    return doc


def check_applies(path: Path, saved: Mapping[str, Any], applying: Mapping[str, Any]) -> None:
    """Under the stack's lock, as ``up`` shows the document it is about to apply: nobody applied since the
    plan was made, and that document is the one reviewed (its plan digest covers every resource and setting)."""
    _same_record(path, (saved.get(SAVED) or {}).get("record"), str(applying.get("stack")))
    if saved.get("plan_digest") != applying.get("plan_digest"):
        was, now = _short(saved.get("plan_digest")), _short(applying.get("plan_digest"))
        raise PlanError(f"saved plan {path} is not what up would apply now (plan digest {was} there, {now} now); "
                        f"{AGAIN}")


Show = Callable[[Mapping[str, Any], tuple[str, ...] | None], None]  # up's showing of the document it will apply


def checked_show(path: Path, plan: Plan, *, manifest: Path, show: Show) -> Show:
    """``up --plan path``: the saved plan checked now (:func:`check_saved_plan`), and ``show`` wrapped so that it
    is checked again under the stack's lock, as the document about to be applied is shown (:func:`check_applies`)."""
    reviewed = check_saved_plan(path, manifest=manifest, stack=plan.stack, target=plan.target, plan=plan)

    def checked(doc: Mapping[str, Any], summary: tuple[str, ...] | None) -> None:
        check_applies(path, reviewed, doc)
        show(doc, summary)

    return checked


def _same_pushed(path: Path, was: Any, now: list[dict[str, Any]]) -> None:
    """The first pushed path whose content changed since the plan, named with its node: a single file (an env
    script, a requirements file) before the folder that may hold it, so the line names what was edited."""
    rows = was if isinstance(was, list) else []
    before = {(r.get("node"), r.get("what"), r.get("path")): r.get("sha256") for r in rows if isinstance(r, dict)}
    for row in sorted(now, key=lambda r: r["what"] in ("workspace", "build")):  # stable: node order kept
        key = (row["node"], row["what"], row["path"])
        if key not in before:
            raise PlanError(f"saved plan {path} does not list the {_WHAT.get(row['what'], row['what'])} {row['path']} "
                            f"node {row['node']} pushes; {AGAIN}")
        if before[key] != row["sha256"]:
            raise PlanError(f"saved plan {path}: node {row['node']}'s {_WHAT.get(row['what'], row['what'])} "
                            f"{row['path']} changed since the plan (sha256 {_short(before[key])} there, "
                            f"{_short(row['sha256'])} now); {AGAIN}")
    if len(before) != len(now):
        raise PlanError(f"saved plan {path} lists pushed files up would not push now; {AGAIN}")


def _same_record(path: Path, was: Any, stack: str) -> None:
    now = record_version(stack)
    if was != now:
        raise PlanError(f"saved plan {path} was made against {_version(was)} of stack {stack}'s record, which is "
                        f"now {_version(now)}: it was applied or removed since; {AGAIN}")


def _version(record: Any) -> str:
    if not isinstance(record, dict):
        return "no record (nothing deployed)"
    return f"serial {_said(record.get('serial'))} (lineage {_said(str(record.get('lineage'))[:8])})"


def _short(digest: Any) -> str:
    return _said(str(digest)[:12])


def _said(value: Any) -> str:
    """A value read from the plan file, as a message may show it: no control or bidirectional character."""
    return visible(str(value))
