"""Hashed workspace sync against a real folder (the local host): only differences travel."""

from __future__ import annotations

import os
from pathlib import Path

from fogiac.provision.local import LocalHost
from fogiac.provision.sync import diff, ignore_patterns, push_tree, scan
from tests.provision.conftest import make_workspace


def test_ignore_patterns_skip_build_outputs_and_fogiacignore(tmp_path: Path) -> None:
    ws = make_workspace(tmp_path / "ws", extra_files=2)
    files = scan(ws, ignore_patterns(ws))
    assert sorted(files) == [
        "src/fogtest/config/params_000.yaml", "src/fogtest/config/params_001.yaml",
        "src/fogtest/launch/talker.launch", "src/fogtest/package.xml", "src/fogtest/scripts/talker.py",
    ]


def test_diff_sends_changed_and_new_files_and_deletes_gone_ones() -> None:
    assert diff({"a": "1", "b": "2", "c": "3"}, {"a": "1", "b": "9", "d": "4"}) == (["b", "c"], ["d"])


def test_repush_sends_one_changed_file_and_removes_deleted_ones(tmp_path: Path) -> None:
    ws = make_workspace(tmp_path / "ws", extra_files=30)
    host = LocalHost(name="box", base=str(tmp_path / "box"))
    host.connect()
    dest = f"{host.base}/ws/demo"
    first = push_tree(host, ws, dest, tmp_dir=f"{host.base}/tmp")
    assert (first.files, first.removed) == (33, 0)
    assert push_tree(host, ws, dest, tmp_dir=f"{host.base}/tmp").changed is False
    (ws / "src/fogtest/config/params_003.yaml").write_text("gain: 2\n")
    (ws / "src/fogtest/config/params_004.yaml").unlink()
    again = push_tree(host, ws, dest, tmp_dir=f"{host.base}/tmp")
    assert (again.files, again.removed) == (1, 1)
    assert again.bytes_sent < first.bytes_sent / 4
    assert Path(dest, "src/fogtest/config/params_003.yaml").read_text() == "gain: 2\n"
    assert not Path(dest, "src/fogtest/config/params_004.yaml").exists()
    assert Path(dest, "src/fogtest/scripts/talker.py").stat().st_mode & 0o111
    assert Path(f"{dest}.sha256sums").read_text().count("\n") == 32


def test_links_are_pushed_as_links_and_never_followed(tmp_path: Path) -> None:
    """A link to a private folder outside the workspace, and two links to the parent (an
    exponential walk when followed): the scan reads nothing behind them, the host gets links."""
    ws = make_workspace(tmp_path / "ws", extra_files=0)
    secret = tmp_path / "home" / ".fogiac"
    secret.mkdir(parents=True)
    (secret / "id_ed25519").write_text("PRIVATE KEY\n")
    (ws / "home").symlink_to(tmp_path / "home")
    for name in ("up1", "up2"):
        (ws / "src" / name).symlink_to("..")
    (ws / "src/fogtest/talker_link.py").symlink_to("scripts/talker.py")
    files = scan(ws, ignore_patterns(ws))
    assert not any("id_ed25519" in rel or rel.startswith(("src/up1/", "src/up2/")) for rel in files)
    assert {"home", "src/up1", "src/up2", "src/fogtest/talker_link.py"} <= set(files)
    host = LocalHost(name="box", base=str(tmp_path / "box"))
    host.connect()
    dest = f"{host.base}/ws/demo"
    push_tree(host, ws, dest, tmp_dir=f"{host.base}/tmp")
    assert Path(dest, "home").is_symlink()
    assert not any("id_ed25519" in names for _, _, names in os.walk(dest))  # the key itself never travelled
    assert Path(dest, "src/up1").readlink() == Path("..")
    assert Path(dest, "src/fogtest/talker_link.py").read_text() == (ws / "src/fogtest/scripts/talker.py").read_text()
    assert push_tree(host, ws, dest, tmp_dir=f"{host.base}/tmp").changed is False


def test_a_workspace_with_only_an_empty_src_is_made_on_the_host(tmp_path: Path) -> None:
    """Issue 26 item 20: nothing to push left no folder, and the env script's `cd` failed at up."""
    ws = tmp_path / "ws"
    (ws / "src").mkdir(parents=True)
    host = LocalHost(name="box", base=str(tmp_path / "box"))
    host.connect()
    dest = f"{host.base}/ws/demo"
    pushed = push_tree(host, ws, dest, tmp_dir=f"{host.base}/tmp", remote_sums="")
    assert (pushed.files, pushed.removed) == (0, 0)
    # what the native runtime runs for an env script: cd into the workspace, then the script
    assert host.run(f"cd {dest} && test -d src && echo set up").stdout == "set up\n"
