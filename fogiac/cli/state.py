"""``fogiac state``: the stacks a shared state store holds, and moving a stack's state in or out of one.

``ls``, ``show``, ``pull`` and ``unlock`` read the store ``--url`` names (default ``$FOGIAC_STATE_URL``,
else the local state folder); ``migrate`` moves one stack's record and files between the local folder
and a shared store, under both stores' locks, and leaves a note where the state was, so a command
run against the old place says where it went instead of "not deployed".
"""

from __future__ import annotations

import getpass
import json
import shutil
import socket
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import typer

from fogiac import deployment
from fogiac.cli._common import need_yes
from fogiac.errors import FogiacError, StateError
from fogiac.pulumi_engine.workspace import BACKEND_DIR, of_stack
from fogiac.state import StackState, held_by, write_atomic
from fogiac.store import STATE_URL, FolderStore, StateStore, check_name, dumps, open_store
from fogiac.tables import console, table

URL = typer.Option(None, "--url", envvar=STATE_URL, show_envvar=True,
                   help="The state store: s3://BUCKET/PREFIX (default: the local state folder).")
STACK = typer.Argument(..., help="The stack: <manifest name>-<environment>, as `fogiac state ls` lists it.")


def _store(url: str | None) -> StateStore:
    return open_store(url or "folder")


def _record(state: StackState) -> dict[str, Any] | None:
    document = state.snapshot().document
    return document if isinstance(document, dict) else None


def _holder(store: StateStore, stack: str) -> dict[str, Any] | None:
    return StackState(stack, store=store).lock_holder()


def rows(store: StateStore, *, now: float | None = None) -> list[dict[str, str]]:
    """One row per stack with a record: target, state, who wrote it last, when, cost so far, the lock."""
    now = time.time() if now is None else now
    out = []
    for stack in store.list():
        state = StackState(stack, store=store)
        try:
            document = _record(state)
        except FogiacError as err:
            out.append({"stack": stack, "target": "?", "state": f"unreadable: {err}", "by": "", "since": "",
                        "cost so far": "", "locked": ""})
            continue
        if document is None:
            continue
        record = _mapping(document.get("deployment"))
        cost = _mapping(_mapping(document.get("applied")).get("cost"))
        hourly, unknown = cost.get("hourly_usd"), cost.get("unknown")
        since = record.get("since_epoch")
        alive = record.get("state") != deployment.REMOVED
        so_far = "—"
        if isinstance(hourly, (int, float)) and isinstance(since, (int, float)) and alive:
            so_far = f"at most ${float(hourly) * max(0.0, now - since) / 3600:.2f} (${float(hourly):.4f}/h)"
            if isinstance(unknown, list) and unknown:  # a price left out of the sum: no bound, as `fogiac ls` says
                so_far = f"unknown (${float(hourly):.4f}/h plus {len(unknown)} unknown)"
        holder = _holder(store, stack)
        out.append({"stack": stack, "target": str(record.get("target", "?")),
                    "state": {"complete": "up", "partial": "partial", "removed": "removed"}.get(
                        str(record.get("state")), str(record.get("state", "?"))),
                    "by": str(document.get("written_by", "?")), "since": str(record.get("since", "?")),
                    "written": str(document.get("written_at", "?")), "cost so far": so_far,
                    "locked": "" if holder is None else held_by(holder)})
    return out


def _mapping(value: object) -> dict[str, Any]:
    return value if isinstance(value, dict) else {}


def _me() -> str:
    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = "?"
    return f"{user}@{socket.gethostname()}"


@contextmanager
def _locked(state: StackState, operation: str) -> Iterator[None]:
    with state.lock(operation=operation):
        yield


def migrate(stack: str, *, to: str, source_url: str | None) -> str:
    """Move ``stack``'s record and files from one store to the other; one line saying what moved."""
    check_name(stack)
    to_folder = to == "folder"
    if not to_folder and source_url not in (None, "folder"):
        raise FogiacError("state migrate goes between the local folder and a shared store: "
                          "--to folder --from s3://..., or --to s3://... from the folder")
    if to_folder and not source_url:
        raise FogiacError(f"state migrate --to folder: which store? pass --from s3://BUCKET/PREFIX or set {STATE_URL}")
    source = open_store("folder") if not to_folder else open_store(source_url)
    dest = open_store(to) if not to_folder else FolderStore()
    src, dst = StackState(stack, store=source), StackState(stack, store=dest)
    with ExitStack() as held:
        held.enter_context(_locked(src, "state migrate"))
        held.enter_context(_locked(dst, "state migrate"))
        dst.clear_moved()  # coming back: the note that it left goes (a failure below leaves no record there)
        there = dst.snapshot().document
        try:
            document = src.snapshot().document
        except StateError as err:  # the source says it moved: a migrate killed once it had written both ends
            if there is None or "its state moved" not in str(err):
                raise
            document = None
        else:  # a bucket notes the move before it drops the record: a record missing from it was never moved here
            if document is None and (there is None or to_folder):
                raise StateError(f"stack {stack!r}: no record in {source.where(stack)} to migrate")
        if document is not None and there is not None and not _same(document, there):
            raise StateError(f"stack {stack!r} already has a record in {dest.where(stack)}; "
                             "nothing was moved (remove one of them first)")
        # A record already there and equal to the source's (or the source's gone) is a migrate killed half-way:
        # this one finishes it. The lock's release pushes a shared store's files.
        files = src.copy_files(dst.ensure()) if document is not None else 0
        if there is None and document is not None:
            dest.put(stack, {**document, "written_by": _me()}, expected=None)
        moved = _move_backend(stack, source, dest, dst.folder, to_folder=to_folder)
        note = {"by": _me(), "at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
        if to_folder:
            note["moved_to"] = f"the folder {dst.folder} on {_me()}"
            forget = getattr(source, "forget_files", None)
            if forget is not None:
                forget(stack)
            source.mark_moved(stack, note["moved_to"], _me())  # type: ignore[attr-defined]
            source.delete(stack)
            source.forget_backend(moved)  # type: ignore[attr-defined]
            shutil.rmtree(src.folder, ignore_errors=True)
        else:
            note["moved_to"] = to.rstrip("/")
            source.delete(stack)
            src.leave_for(note)
    return (f"moved stack {stack!r} ({files} file(s) beside its record) from {source.where(stack)} to "
            f"{dest.where(stack)}")


def _move_backend(stack: str, source: StateStore, dest: StateStore, folder: Path, *, to_folder: bool) -> list[str]:
    """Copy the stack's Pulumi state (a cloud target's file backend) to where the engine looks for it once the
    record moved: the stack folder's ``pulumi/.pulumi/`` tree into the bucket's ``.pulumi/`` (the engine's
    ``s3://`` backend, the same prefix), or the stack's own files of the bucket's tree into the folder.
    Returns what the source may drop once the record is written (for the bucket: after the copy is whole)."""
    if to_folder:
        files = source.backend_files(lambda rel: of_stack(stack, rel) or rel == "meta.yaml")  # type: ignore[attr-defined]
        tree = folder / BACKEND_DIR / ".pulumi"
        for rel, data in sorted(files.items()):
            target = tree.joinpath(*rel.split("/"))
            target.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
            write_atomic(target, data, mode=0o600)
        return [rel for rel in files if rel != "meta.yaml"]  # the bucket's meta stays: other stacks use it
    tree = source.folder(stack) / BACKEND_DIR / ".pulumi"
    put = getattr(dest, "put_backend", None)
    if put is None or not tree.is_dir():
        return []
    for path in sorted(p for p in tree.rglob("*") if p.is_file() and not p.is_symlink()):
        rel = path.relative_to(tree).as_posix()
        if rel.split("/")[0] != "locks":  # a dead update's lock stays behind: Pulumi's own lock is per machine
            put(rel, path.read_bytes(), if_absent=rel == "meta.yaml")  # a bucket in use keeps its own meta
    return []


def _same(one: dict[str, Any], other: dict[str, Any]) -> bool:
    """The same record but for who wrote it (``migrate`` stamps the copy with the member who moved it)."""
    return {k: v for k, v in one.items() if k != "written_by"} == {k: v for k, v in other.items() if k != "written_by"}


def register(app: typer.Typer) -> None:
    group = typer.Typer(help="The stacks in a state store (local folder or shared s3://); move a stack between them.",
                        no_args_is_help=True)

    @group.command("ls")
    def ls(url: str | None = URL) -> None:
        """Every stack in the store: target, state, who wrote it last, since when, cost so far, its lock."""
        store = _store(url)
        found = rows(store)
        if not found:
            typer.echo(f"no stacks in {url or 'the local state folder'}")
            return
        columns = ["stack", "target", "state", "by", "since", "cost so far", "locked"]
        out = table(None, *columns)
        for row in found:
            out.add_row(*(row[c] for c in columns))
        console().print(out)

    @group.command("show")
    def show(stack: str = STACK, url: str | None = URL) -> None:
        """The stack's record as the store holds it (JSON), with who holds its lock."""
        store = _store(url)
        state = StackState(stack, store=store)
        document = _record(state)
        if document is None:
            raise StateError(f"stack {stack!r}: no record in {store.where(stack)}")
        holder = _holder(store, stack)
        typer.echo(json.dumps({"where": store.where(stack), "locked": None if holder is None else held_by(holder),
                               "record": document}, indent=2, sort_keys=True))

    @group.command("pull")
    def pull(stack: str = STACK, url: str | None = URL,
             into: Path = typer.Option(None, "--into", help="The folder to write (default: ./<stack>-state).")) -> None:
        """A local copy of the stack's record and files, for reading (fogiac never reads it back)."""
        store = _store(url)
        state = StackState(stack, store=store)
        document = _record(state)
        if document is None:
            raise StateError(f"stack {stack!r}: no record in {store.where(stack)}")
        folder = into or Path(f"{stack}-state")
        if folder.exists() and any(folder.iterdir()):
            raise FogiacError(f"{folder}: not empty; pass --into with a new folder")
        folder.mkdir(parents=True, exist_ok=True, mode=0o700)
        write_atomic(folder / StackState.RECORD, dumps(document), mode=0o600)
        count = state.copy_files(folder)
        typer.echo(f"wrote {folder} (the record and {count} file(s), as of serial {document.get('serial')}); "
                   "a copy for reading: fogiac keeps using the store")

    @group.command("migrate")
    def migrate_(stack: str = STACK,
                 to: str = typer.Option(..., "--to", help="s3://BUCKET/PREFIX, or `folder` (the local state folder)."),
                 source: str | None = typer.Option(None, "--from", envvar=STATE_URL, show_envvar=True,
                                                   help="With --to folder: the shared store it leaves.")) -> None:
        """Move a stack's state from the local folder to a shared store, or back; the old place says where."""
        typer.echo(migrate(stack, to=to, source_url=source if to == "folder" else None))

    @group.command("unlock")
    def unlock(stack: str = STACK, url: str | None = URL, yes: bool = typer.Option(False, "--yes", "-y",
                                                                               help="Do not ask.")) -> None:
        """Break the stack's lock, whose holder is gone (a killed or crashed `up` on any member's machine)."""
        store = _store(url)
        check_name(stack)
        holder = _holder(store, stack)
        if holder is None:
            typer.echo(f"stack {stack!r} is not locked ({store.where(stack, StackState.LOCK)})")
            return
        line = held_by(holder)
        if not yes:
            need_yes(yes, f"break the lock of {stack!r} ({line})")
            if not typer.confirm(f"break the lock of {stack!r}: {line}?"):
                raise FogiacError("not unlocked: nothing was changed")
        store.break_lock(stack, holder)
        if _holder(store, stack) is not None:
            raise StateError(f"stack {stack!r}: the lock changed while breaking it (another took it): "
                             f"{held_by(_holder(store, stack) or {})}")
        typer.echo(f"broke the lock of stack {stack!r}: {line}")

    app.add_typer(group, name="state")
