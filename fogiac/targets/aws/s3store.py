"""Stack records in S3, so a lab's members share them: the :class:`~fogiac.store.StateStore` of ``s3://``.

Layout under ``s3://BUCKET/PREFIX/``::

    <stack>/record.json       the record; replaced only by a put whose If-Match names the ETag read
                              (created with If-None-Match: *), so a writer that read an older record is
                              refused, never overwrites (S3's writes are whole: a kill -9 leaves old or new)
    <stack>/lock.json         who holds the stack: created with If-None-Match: *, dropped with If-Match
    <stack>/files/<path>      the stack folder's other files (certificates, keys, known hosts, a target's
                              own), each sealed by :mod:`fogiac.sealed` before it leaves
    <stack>/moved.json        the stack's state went back to a member's folder (``fogiac state migrate``)
    .pulumi/                  the Pulumi engine's backend (``s3://BUCKET/PREFIX``: Pulumi writes ``.pulumi/``)

The files are worked on where every command finds them, a local folder (a cache under the state folder,
``.s3/<bucket>/<prefix>/<stack>``): they are pulled when a command first asks for the folder and again
once it holds the lock, and pushed (only by the lock's holder) with each record write and when the lock is
released, so a ``kill -9`` loses at most what changed since the last record write. A file another member
removed is removed here on the next pull; one removed here is removed there on the next push (the
``.index`` beside the cache remembers what was last synced, and which object version it was).

A lock whose holder is gone is never taken over here: the holder may be on another member's machine,
where "gone" cannot be seen. It is reported with its holder, and ``fogiac state unlock`` breaks it.

boto3 is imported when a store is made: the first day on the folder store loads nothing of this.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from fogiac.errors import CredentialsError, StateError
from fogiac.sealed import Sealer, sealer_for
from fogiac.store import LOCK, RECORD, Snapshot, StaleRecord, check_name, dumps, make_private, state_root, write_atomic
from fogiac.targets.aws.sdk import need

FILES = "files/"
MOVED = "moved.json"
INDEX = ".index"  # beside the cached stacks: what each stack's last sync saw (never itself synced)
_CONFLICT = {"PreconditionFailed", "ConditionalRequestConflict", "412", "409"}
_MISSING = {"NoSuchKey", "404", "NotFound"}
_DENIED = {"AccessDenied", "InvalidAccessKeyId", "SignatureDoesNotMatch", "ExpiredToken", "403"}


def parse_url(url: str) -> tuple[str, str]:
    """``s3://bucket/prefix`` as (bucket, prefix without slashes at either end); anything else one line."""
    parts = urlsplit(url)
    prefix = parts.path.strip("/")
    if parts.scheme != "s3" or not parts.netloc or parts.query or parts.fragment or "//" in parts.path \
            or any(p in (".", "..") for p in prefix.split("/")):
        raise StateError(f"state url {url!r}: expected s3://BUCKET/PREFIX")
    return parts.netloc, prefix


def _code(err: BaseException) -> str:
    response = getattr(err, "response", None)
    if isinstance(response, dict):
        error = response.get("Error", {})
        return str(error.get("Code") or response.get("ResponseMetadata", {}).get("HTTPStatusCode", ""))
    return ""


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


class S3Store:
    """Stack records, locks and files under ``s3://bucket/prefix``; see the module's docstring."""

    reclaims_dead_holders = False

    def __init__(self, url: str, *, kms_key: str | None = None, client: Any | None = None,
                 cache: Path | None = None, sealer: Sealer | None = None) -> None:
        self.url = url.rstrip("/")
        self.bucket, self.prefix = parse_url(url)
        self.kms_key = kms_key
        self._client = client
        self._cache = cache
        self._sealer = sealer
        self._held: dict[str, str] = {}  # stack -> the ETag of the lock this process holds
        self._pulled: set[str] = set()

    @classmethod
    def from_url(cls, url: str, *, kms_key: str | None = None) -> S3Store:
        return cls(url, kms_key=kms_key)

    def __repr__(self) -> str:
        return f"S3Store({self.url!r})"

    # -- plumbing --------------------------------------------------------------------------------------

    @property
    def client(self) -> Any:
        if self._client is None:
            boto3 = need("boto3")
            config = need("botocore.config").Config(connect_timeout=5, read_timeout=30,
                                                     retries={"max_attempts": 3, "mode": "standard"})
            self._client = boto3.session.Session().client("s3", config=config)
        return self._client

    @property
    def sealer(self) -> Sealer:
        if self._sealer is None:
            self._sealer = sealer_for(self.kms_key)
        return self._sealer

    @property
    def cache(self) -> Path:
        """Where this bucket's stacks' files are worked on, on this machine."""
        if self._cache is None:
            self._cache = state_root() / ".s3" / self.bucket / (self.prefix.replace("/", "+") or "+")
        return self._cache

    def key(self, stack: str, name: str) -> str:
        return "/".join(p for p in (self.prefix, check_name(stack), name) if p)

    @property
    def backend_url(self) -> str:
        """The Pulumi engine's backend: the same bucket and prefix (Pulumi keeps its own ``.pulumi/`` there)."""
        return self.url

    def _call(self, what: str, op: str, **kwargs: Any) -> Any:
        """One S3 request; a credential or access failure is one line naming the bucket and what was asked."""
        errors = need("botocore.exceptions")
        try:
            return getattr(self.client, op)(Bucket=self.bucket, **kwargs)
        except (errors.NoCredentialsError, errors.PartialCredentialsError):
            raise CredentialsError(f"{what}: no AWS credentials found for the state bucket s3://{self.bucket} "
                                   "(set AWS_PROFILE, or AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY)") from None
        except errors.ClientError as err:
            code = _code(err)
            if code in _DENIED:
                raise CredentialsError(f"{what}: access denied to s3://{self.bucket}/{kwargs.get('Key', self.prefix)} "
                                       f"({code}); the IAM policy must allow it (see docs/guides/teams.md)") from None
            if code == "NoSuchBucket":
                raise StateError(f"{what}: the state bucket s3://{self.bucket} does not exist") from None
            raise
        except (errors.EndpointConnectionError, errors.ConnectTimeoutError, errors.ReadTimeoutError) as err:
            raise StateError(f"{what}: the state bucket s3://{self.bucket} does not answer ({err})") from None

    def _get(self, what: str, key: str) -> tuple[bytes, str, dict[str, str]] | None:
        errors = need("botocore.exceptions")
        try:
            got = self._call(what, "get_object", Key=key)
        except errors.ClientError as err:
            if _code(err) in _MISSING:
                return None
            raise StateError(f"{what}: {_code(err) or err}") from None
        return got["Body"].read(), str(got["ETag"]), dict(got.get("Metadata") or {})

    def _put(self, what: str, key: str, body: bytes, **conditions: Any) -> str | None:
        """Write ``body`` if ``conditions`` hold; the new ETag, or None when a condition failed."""
        errors = need("botocore.exceptions")
        try:
            done = self._call(what, "put_object", Key=key, Body=body, **conditions)
        except errors.ClientError as err:
            if _code(err) in _CONFLICT:
                return None
            raise StateError(f"{what}: s3://{self.bucket}/{key}: {_code(err) or err}") from None
        return str(done["ETag"])

    def _delete(self, what: str, key: str, **conditions: Any) -> bool:
        """Delete ``key`` (if its ETag is still ``IfMatch``); False when the condition failed.

        Where the store has no conditional delete (LocalStack, older S3 compatibles answer NotImplemented),
        the ETag is read first: a lock replaced in the instant between is the one race left there."""
        errors = need("botocore.exceptions")
        try:
            self._call(what, "delete_object", Key=key, **conditions)
        except errors.ClientError as err:
            if _code(err) in _CONFLICT:
                return False
            if _code(err) in _MISSING:
                return True
            if _code(err) == "NotImplemented" and "IfMatch" in conditions:
                found = self._get(what, key)
                if found is not None and found[1] != conditions["IfMatch"]:
                    return False
                return self._delete(what, key)
            raise StateError(f"{what}: {_code(err) or err}") from None
        return True

    def _keys(self, what: str, prefix: str, *, delimiter: str | None = None) -> Iterator[dict[str, Any]]:
        token: str | None = None
        while True:
            extra: dict[str, Any] = {"Delimiter": delimiter} if delimiter else {}
            if token:
                extra["ContinuationToken"] = token
            page = self._call(what, "list_objects_v2", Prefix=prefix, **extra)
            yield from page.get("Contents", [])
            yield from ({"Prefix": p["Prefix"]} for p in page.get("CommonPrefixes", []))
            if not page.get("IsTruncated"):
                return
            token = page.get("NextContinuationToken")

    def where(self, stack: str, name: str = RECORD) -> str:
        return f"s3://{self.bucket}/{self.key(stack, name)}"

    # -- the record ------------------------------------------------------------------------------------

    def get(self, stack: str) -> Snapshot:
        where = self.where(stack)
        found = self._get(where, self.key(stack, RECORD))
        if found is None:
            moved = self._get(where, self.key(stack, MOVED))
            if moved is not None:
                raise StateError(moved_line(stack, moved[0], here=self.url))
            return Snapshot(None, None)
        raw, etag, _ = found
        try:
            document = json.loads(raw)
        except ValueError as err:
            raise StateError(f"{where}: unreadable state file ({err})") from None
        if not isinstance(document, dict):
            raise StateError(f"{where}: not a fogiac stack record; remove it if the stack is gone")
        return Snapshot(document, etag)

    def put(self, stack: str, document: Mapping[str, Any], *, expected: str | None) -> str:
        where = self.where(stack)
        condition = {"IfMatch": expected} if expected is not None else {"IfNoneMatch": "*"}
        etag = self._put(where, self.key(stack, RECORD), dumps(document), ContentType="application/json",
                         **condition)
        if etag is None:
            raise StaleRecord(f"{where}: the stack's record changed since it was read (another fogiac wrote it); "
                              "nothing was written, run the command again")
        self._delete(where, self.key(stack, MOVED))
        if stack in self._held:
            self.push(stack)
        return etag

    def delete(self, stack: str) -> None:
        self._delete(self.where(stack), self.key(stack, RECORD))

    def list(self) -> list[str]:
        """The stacks with a folder in the bucket, sorted (Pulumi's ``.pulumi/`` is no stack)."""
        base = f"{self.prefix}/" if self.prefix else ""
        names = (entry["Prefix"][len(base):].rstrip("/") for entry in self._keys(self.url, base, delimiter="/")
                 if "Prefix" in entry)
        return sorted(n for n in names if n and not n.startswith("."))

    # -- the lock --------------------------------------------------------------------------------------

    def acquire(self, stack: str, holder: Mapping[str, Any]) -> dict[str, Any] | None:
        where = self.where(stack, LOCK)
        etag = self._put(where, self.key(stack, LOCK), json.dumps(dict(holder)).encode(), IfNoneMatch="*",
                         ContentType="application/json")
        if etag is None:
            found = self.lock_holder(stack)
            return found if found is not None else {}
        self._held[stack] = etag
        try:
            self.pull(stack)  # what the last holder left, now that nobody else writes
        except BaseException:
            self.release(stack, holder)
            raise
        return None

    def lock_holder(self, stack: str) -> dict[str, Any] | None:
        """Who holds the stack's lock (``{}``: a lock that does not read as a holder), or None: unlocked."""
        found = self._get(self.where(stack, LOCK), self.key(stack, LOCK))
        if found is None:
            return None
        try:
            holder = json.loads(found[0])
        except ValueError:
            return {}
        return holder if isinstance(holder, dict) else {}

    def release(self, stack: str, holder: Mapping[str, Any]) -> None:
        """Push the files, then drop the lock this process took (only that lock: If-Match its ETag)."""
        etag = self._held.get(stack)
        if etag is None:
            return
        try:
            self.push(stack)
        finally:
            self._held.pop(stack, None)
            self._delete(self.where(stack, LOCK), self.key(stack, LOCK), IfMatch=etag)

    def break_lock(self, stack: str, holder: Mapping[str, Any]) -> None:
        """Remove the lock while it still names ``holder`` (one taken since by another stays)."""
        where = self.where(stack, LOCK)
        found = self._get(where, self.key(stack, LOCK))
        if found is None:
            return
        try:
            current = json.loads(found[0])
        except ValueError:
            current = {}
        if current == dict(holder) or (not holder and not isinstance(current, dict)):
            self._delete(where, self.key(stack, LOCK), IfMatch=found[1])

    # -- the stack's files -----------------------------------------------------------------------------

    def folder(self, stack: str, *, create: bool = False) -> Path:
        """The stack's files on this machine, pulled from the bucket the first time a command asks."""
        path = self.cache / check_name(stack)
        if stack not in self._pulled:
            self._pulled.add(stack)
            self.pull(stack)
        return make_private(path) if create else path

    def _index_path(self, stack: str) -> Path:
        return self.cache / INDEX / f"{stack}.json"

    def _index(self, stack: str) -> dict[str, dict[str, str]]:
        try:
            data = json.loads(self._index_path(stack).read_text())
        except (OSError, ValueError):
            return {}
        return data if isinstance(data, dict) else {}

    def _save_index(self, stack: str, index: Mapping[str, Mapping[str, str]]) -> None:
        path = self._index_path(stack)
        path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        write_atomic(path, dumps(index), mode=0o600)

    def remote_files(self, stack: str) -> dict[str, str]:
        """Each file object of the stack: path in the folder -> ETag."""
        base = self.key(stack, FILES)
        return {entry["Key"][len(base):]: str(entry["ETag"]) for entry in self._keys(self.where(stack), base)
                if "Key" in entry and entry["Key"] != base}

    def pull(self, stack: str) -> None:
        """Bring the folder up to what the bucket holds (each file opened by the sealer, 0600 or its mode)."""
        folder = self.cache / check_name(stack)
        index = self._index(stack)
        remote = self.remote_files(stack)
        for rel, etag in sorted(remote.items()):
            path = _inside(folder, rel)
            if path is None:
                continue
            if index.get(rel, {}).get("etag") == etag and path.is_file():
                continue
            found = self._get(self.where(stack), self.key(stack, FILES + rel))
            if found is None:
                continue  # removed since listed
            blob, etag, meta = found
            data = self.sealer.open(rel, blob)
            _mkdirs(folder, path.parent)
            write_atomic(path, data, mode=_mode(meta.get("mode")))
            index[rel] = {"etag": etag, "digest": _digest(data)}
        for rel in [r for r in index if r not in remote]:
            path = _inside(folder, rel)
            if path is not None:
                path.unlink(missing_ok=True)
            del index[rel]
        if index or self._index_path(stack).exists():
            self._save_index(stack, index)

    def push(self, stack: str) -> None:
        """Send what changed in the folder since the last sync, and remove what was removed here."""
        folder = self.cache / check_name(stack)
        index = self._index(stack)
        local = dict(_files(folder))
        for rel, path in sorted(local.items()):
            data = path.read_bytes()
            digest = _digest(data)
            if index.get(rel, {}).get("digest") == digest:
                continue
            mode = f"{stat.S_IMODE(path.stat().st_mode) & 0o700:o}"
            etag = self._put(self.where(stack), self.key(stack, FILES + rel), self.sealer.seal(rel, data),
                             Metadata={"mode": mode})
            index[rel] = {"etag": etag or "", "digest": digest}
        for rel in [r for r in index if r not in local]:
            self._delete(self.where(stack), self.key(stack, FILES + rel))
            del index[rel]
        self._save_index(stack, index)

    def forget_files(self, stack: str) -> None:
        """Every file object of the stack and its cache (``state migrate`` moved them elsewhere)."""
        for rel in self.remote_files(stack):
            self._delete(self.where(stack), self.key(stack, FILES + rel))
        self._index_path(stack).unlink(missing_ok=True)

    def clear_moved(self, stack: str) -> None:
        self._delete(self.where(stack), self.key(stack, MOVED))

    def mark_moved(self, stack: str, to: str, by: str) -> None:
        self._put(self.where(stack), self.key(stack, MOVED),
                  dumps({"moved_to": to, "by": by, "at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}))


def moved_line(stack: str, raw: bytes, *, here: str) -> str:
    """The one line a store says when a stack's state was migrated away from it."""
    try:
        note = json.loads(raw)
    except ValueError:
        note = {}
    to = str(note.get("moved_to", "?")) if isinstance(note, dict) else "?"
    by = str(note.get("by", "?")) if isinstance(note, dict) else "?"
    return (f"stack {stack!r}: its state moved from {here} to {to} (fogiac state migrate by {by}); "
            + ("unset FOGIAC_STATE_URL to use it" if not to.startswith("s3://") else f"set FOGIAC_STATE_URL={to}"))


def _inside(folder: Path, rel: str) -> Path | None:
    """``rel`` under ``folder``, or None for a name that would leave it (an object key someone else wrote)."""
    parts = rel.split("/")
    if not rel or any(p in ("", ".", "..") or p.startswith(".") for p in parts):
        return None
    return folder.joinpath(*parts)


def _mkdirs(folder: Path, path: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True, mode=0o700)
    path.mkdir(parents=True, exist_ok=True, mode=0o700)


def _mode(text: str | None) -> int:
    """A file's mode as pushed (owner bits only: group and others never get a stack's file)."""
    try:
        mode = int(text or "600", 8) & 0o700
    except ValueError:
        mode = 0o600
    return mode | 0o600


def _files(folder: Path) -> Iterator[tuple[str, Path]]:
    """The stack folder's regular files by relative path (dot-names are scratch: never synced; logs stay)."""
    if not folder.is_dir():
        return
    for root, dirs, names in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for name in sorted(names):
            path = Path(root) / name
            if name.startswith(".") or name.endswith(".log") or not path.is_file() or path.is_symlink():
                continue
            yield path.relative_to(folder).as_posix(), path
