"""A host without a package index gets its wheels from the operator's machine (issue 26 item 26).

A lab host that cannot reach an index failed at ``pip install`` of fogiac's and the workloads'
requirements. The host here is a real folder run by bash whose pip sees no index (``PIP_NO_INDEX``,
no config): the failure names the opt-in; with ``FOGIAC_CARRY_WHEELS=1`` the operator's pip downloads
the wheels once into a cache named by their digest, they are pushed once, and the host installs them.
"""

from __future__ import annotations

import platform
import shutil
import sys
from pathlib import Path

import pytest

from fogiac.errors import ProvisionError
from fogiac.provision import venv
from fogiac.provision.host import Result
from fogiac.provision.local import LocalHost

PYTHON = "/usr/bin/python3"
NO_INDEX = "export PIP_NO_INDEX=1 PIP_CONFIG_FILE=/dev/null PIP_FIND_LINKS= PIP_EXTRA_INDEX_URL=; "

pytestmark = pytest.mark.skipif(shutil.which(PYTHON) is None, reason=f"needs {PYTHON}")


class OfflineHost(LocalHost):
    """The lab host: its pip reaches no index and no wheel folder of this machine."""

    def run(self, command: str, *, check: bool = True, timeout: float | None = None) -> Result:
        return super().run(NO_INDEX + command, check=check, timeout=timeout)


def _ensure(host: LocalHost, tmp_path: Path) -> venv.Venv:
    return venv.ensure(host, root=f"{host.base}/venv", marker=f"{host.base}/venv.sha256", known="", reqs=("iniconfig",),
                       python=PYTHON, allow_install=False, log=f"{host.base}/venv-install.log")


def test_without_an_index_the_error_names_the_opt_in(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(venv.CARRY_ENV, raising=False)
    host = OfflineHost(name="lab1", base=str(tmp_path / "lab1"))
    host.connect()
    with pytest.raises(ProvisionError, match=r"^lab1: installing the workloads' requirements failed .* \(a host "
                                             r"without a package index: set FOGIAC_CARRY_WHEELS=1 here"):
        _ensure(host, tmp_path)


def test_carried_wheels_install_offline_and_travel_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(venv.CARRY_ENV, "1")
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "state"))
    host = OfflineHost(name="lab1", base=str(tmp_path / "lab1"))
    host.connect()
    made = _ensure(host, tmp_path)
    assert made.built
    assert host.run(f"{made.python} -c 'import iniconfig; print(iniconfig.__name__)'").stdout == "iniconfig\n"
    (cached,) = (tmp_path / "state" / "wheels").iterdir()  # the operator's cache, by digest
    assert [p.name for p in cached.iterdir() if p.name.startswith("iniconfig-")]
    sent = host.bytes_sent
    again = venv.carry_wheels(host, ("iniconfig",), python=PYTHON, root=f"{host.base}/venv")
    assert again.endswith(cached.name) and host.bytes_sent == sent  # on the host already: nothing pushed


def _sdist_that_runs_code(folder: Path, marker: Path) -> None:
    """A source-only release whose build backend leaves ``marker`` when pip asks it anything."""
    import io  # noqa: PLC0415
    import tarfile  # noqa: PLC0415

    backend = (f"import pathlib\npathlib.Path({str(marker)!r}).write_text('built on the operator machine')\n"
               "def get_requires_for_build_wheel(config_settings=None):\n    return []\n"
               "def prepare_metadata_for_build_wheel(d, config_settings=None):\n    raise SystemExit(1)\n")
    files = {"pyproject.toml": '[build-system]\nrequires = []\nbuild-backend = "backend"\nbackend-path = ["."]\n',
             "backend.py": backend, "PKG-INFO": "Metadata-Version: 2.1\nName: sdistonly\nVersion: 1.0\n"}
    folder.mkdir()
    with tarfile.open(folder / "sdistonly-1.0.tar.gz", "w:gz") as tar:
        for name, text in files.items():
            info = tarfile.TarInfo(f"sdistonly-1.0/{name}")
            info.size = len(text.encode())
            tar.addfile(info, io.BytesIO(text.encode()))


def test_carrying_never_builds_a_source_release_here(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 35 item 9: for the host's own Python too, pip downloads wheels only; a package released as
    source alone is refused on the operator's machine before its build code runs."""
    marker = tmp_path / "ran"
    _sdist_that_runs_code(tmp_path / "links", marker)
    for key, value in {"PIP_CONFIG_FILE": "/dev/null", "PIP_NO_INDEX": "1", "PIP_EXTRA_INDEX_URL": "",
                       "PIP_FIND_LINKS": str(tmp_path / "links")}.items():
        monkeypatch.setenv(key, value)
    here = f"{sys.version_info[0]}.{sys.version_info[1]}"
    with pytest.raises(ProvisionError, match=r"^carrying wheels \(FOGIAC_CARRY_WHEELS=1\): pip download on this "
                                             r"machine failed: .*sdistonly"):
        venv._download(("sdistonly",), version=here, machine=platform.machine(), into=tmp_path / "wheels")
    assert not marker.exists()
    assert not (tmp_path / "wheels").exists()
