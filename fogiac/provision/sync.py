"""Push a folder to a host sending only what changed, by content hash.

Why: workspaces hold meshes, weights and build leftovers; a second ``up`` must not resend them.
The host keeps ``<dest>.sha256sums`` (``sha256  path`` lines, the ``sha256sum`` format) of what
it received; a push compares it with the local folder and sends one gzip'd tar with the
changed files and only the checksum lines that changed (the host merges them with ``awk``),
then deletes files that went away.

Symbolic links are never followed: a link is pushed as a link (its target text, as it is), so a
link to ``/`` or ``~`` cannot carry the operator's files (``~/.fogiac`` keys included) to a host,
and links to a parent folder cannot make the walk exponential.
"""

from __future__ import annotations

import fnmatch
import hashlib
import io
import os
import tarfile
import time
from dataclasses import dataclass
from pathlib import Path

from fogiac.provision.host import Host, q

DEFAULT_IGNORE = (".git/", ".hg/", ".svn/", "build/", "devel/", "install/", "log/", "logs/",
                  "__pycache__/", "*.pyc", ".pytest_cache/", ".mypy_cache/", "*.swp", ".DS_Store",
                  ".fogiacignore", ".catkin_tools/", ".venv/")


@dataclass(frozen=True)
class Pushed:
    """What a push did: files sent (added or changed), files removed, bytes put on the wire."""

    files: int
    removed: int
    bytes_sent: int
    digest: str

    @property
    def changed(self) -> bool:
        return bool(self.files or self.removed)


def ignore_patterns(root: Path, extra: tuple[str, ...] = ()) -> tuple[str, ...]:
    """The defaults, then ``.fogiacignore`` lines (gitignore-like: ``dir/``, globs, ``#`` comments)."""
    patterns = list(DEFAULT_IGNORE) + list(extra)
    ignore_file = root / ".fogiacignore"
    if ignore_file.is_file():
        for line in ignore_file.read_text().splitlines():
            line = line.strip()
            if line and not line.startswith("#"):
                patterns.append(line.lstrip("/"))
    return tuple(patterns)


def _ignored(rel: str, is_dir: bool, patterns: tuple[str, ...]) -> bool:
    name = rel.rsplit("/", 1)[-1]
    for pattern in patterns:
        if pattern.endswith("/"):
            if not is_dir:
                continue
            pattern = pattern[:-1]
        target = rel if "/" in pattern else name
        if fnmatch.fnmatchcase(target, pattern):
            return True
    return False


def scan(root: Path, patterns: tuple[str, ...]) -> dict[str, str]:
    """``{relative path: sha256}`` of every file and link under ``root`` not ignored; a link's hash is
    of its target text, and nothing behind a link is read."""
    out: dict[str, str] = {}
    todo = [root]
    while todo:
        folder = todo.pop()
        for entry in sorted(folder.iterdir()):
            rel = entry.relative_to(root).as_posix()
            if entry.is_symlink():
                if not _ignored(rel, False, patterns):
                    out[rel] = hashlib.sha256(b"symlink\0" + os.fsencode(os.readlink(entry))).hexdigest()
            elif entry.is_dir():
                if not _ignored(rel, True, patterns):
                    todo.append(entry)
            elif entry.is_file() and not _ignored(rel, False, patterns):
                out[rel] = hashlib.sha256(entry.read_bytes()).hexdigest()
    return out


def sums_text(hashes: dict[str, str]) -> str:
    return "".join(f"{digest}  {path}\n" for path, digest in sorted(hashes.items()))


def parse_sums(text: str) -> dict[str, str]:
    out = {}
    for line in text.splitlines():
        digest, sep, path = line.partition("  ")
        if sep and len(digest) == 64:
            out[path] = digest
    return out


def digest_of(hashes: dict[str, str]) -> str:
    return hashlib.sha256(sums_text(hashes).encode()).hexdigest()


def diff(local: dict[str, str], remote: dict[str, str]) -> tuple[list[str], list[str]]:
    """(paths to send, paths to delete on the host)."""
    send = sorted(p for p, h in local.items() if remote.get(p) != h)
    delete = sorted(p for p in remote if p not in local)
    return send, delete


def _member(tar: tarfile.TarFile, name: str, data: bytes, mode: int) -> None:
    info = tarfile.TarInfo(name)
    info.size, info.mode, info.mtime = len(data), mode, int(time.time())
    tar.addfile(info, io.BytesIO(data))


def _tarball(root: Path, send: list[str], drop: list[str], local: dict[str, str], *, dest_name: str) -> bytes:
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:gz", compresslevel=9) as tar:
        for rel in send:
            src = root / rel
            if src.is_symlink():
                link = tarfile.TarInfo(f"{dest_name}/{rel}")
                link.type, link.linkname, link.mtime = tarfile.SYMTYPE, os.readlink(src), int(time.time())
                tar.addfile(link)
                continue
            _member(tar, f"{dest_name}/{rel}", src.read_bytes(), 0o755 if src.stat().st_mode & 0o111 else 0o644)
        _member(tar, f"{dest_name}.delta", sums_text({p: local[p] for p in send}).encode(), 0o600)
        _member(tar, f"{dest_name}.drop", "".join(f"{p}\n" for p in drop).encode(), 0o600)
    return buf.getvalue()


# Keep checksum lines whose path (from column 67: 64 hex digits, two spaces) is not dropped,
# then add the new lines: the host's checksum list now describes exactly what it holds.
_MERGE = ("awk 'NR==FNR {{drop[$0]=1; next}} !(substr($0, 67) in drop)' {n}.drop {n}.sha256sums > {n}.merge "
          "2>/dev/null; cat {n}.delta >> {n}.merge && mv {n}.merge {n}.sha256sums && rm -f {n}.drop {n}.delta")


def push_tree(host: Host, root: Path, dest: str, *, tmp_dir: str, extra_ignore: tuple[str, ...] = (),
              remote_sums: str | None = None) -> Pushed:
    """Make ``dest`` on ``host`` hold exactly ``root``'s non-ignored files; send only differences.

    ``remote_sums``: the host's checksum list when a probe already read it ('' if absent).
    """
    local = scan(root, ignore_patterns(root, extra_ignore))
    digest = digest_of(local)
    if remote_sums is None:
        found = host.run(f"cat {q(dest + '.sha256sums')} 2>/dev/null", check=False)
        remote_sums = found.stdout
    remote = parse_sums(remote_sums)
    send, delete = diff(local, remote)
    if not send and not delete:
        if not local:  # no file to carry (only an empty src/): the folder is still made, for the env scripts
            host.run(f"mkdir -p {q(dest)}" + (f" {q(dest + '/src')}" if (root / "src").is_dir() else ""))
        return Pushed(files=0, removed=0, bytes_sent=0, digest=digest)
    parent, dest_name = dest.rsplit("/", 1)
    blob = _tarball(root, send, sorted(send + delete), local, dest_name=dest_name)
    archive = f"{tmp_dir}/{dest_name}.tgz"
    host.run(f"mkdir -p {q(tmp_dir)} {q(dest)}")
    sent = host.put(blob, archive, mode=0o600)
    removals = " ".join(q(f"{dest}/{p}") for p in delete)
    host.run(f"tar -xzf {q(archive)} -C {q(parent)} && rm -f {q(archive)} && cd {q(parent)} && "
             + _MERGE.format(n=q(dest_name)) + (f" && rm -f {removals}" if removals else ""))
    return Pushed(files=len(send), removed=len(delete), bytes_sent=sent, digest=digest)
