"""Real SSH hosts for provisioning tests: network namespaces, each running its own sshd.

Why: provisioning is SSH, files and processes; faking any of them would test the fake. Each
"host" is a namespace joined to the root namespace by a veth pair (10.232.K.2, K unique per
test process: see ``_octet_base``), running Debian's ``/usr/sbin/sshd -D`` with a generated
ed25519 host key and one authorized key. Namespaces share the filesystem, so every host gets its
own ``base_dir``. Used by the tests and by ``benchmarks/provision.py``; cleanup (sshd, every
process started in a namespace, the namespaces) runs even when the caller fails.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import pwd
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Iterator

from tests.support.netns import NetLab, Namespace, skip_reason

SSHD = "/usr/sbin/sshd"

# A lab's pip setting for hosts that build a workload's venv (torch, sympy: thousands of modules): pip leaves
# byte-compiling to Python, which compiles what the nodes import, on first import. Compiling every module at
# install was half of the venv's CPU (272 s against 141 s for fogiac's and the workloads' requirements,
# measured on this 2-core machine under load). pip sets an option's destination from its variable, so the
# variable of ``--no-compile`` (destination ``compile``) says 0 for "do not compile".
PIP_LEAVES_COMPILING = {"PIP_NO_COMPILE": "0"}


def lab_skip_reason() -> str | None:
    reason = skip_reason()
    if reason:
        return reason
    if not Path(SSHD).exists():
        return "needs Debian's openssh-server (/usr/sbin/sshd)"
    if shutil.which("ssh-keygen") is None:
        return "needs ssh-keygen (openssh-client)"
    return None


@dataclass(frozen=True)
class LabHost:
    name: str
    address: str
    ns: Namespace
    host_key_pub: Path
    base_dir: Path


def kill_host(host: LabHost) -> None:
    """Every process of the host's namespace but sshd (the machine died; the lab's login stays for teardown)."""
    for pid in host.ns.pids():
        with contextlib.suppress(OSError):
            if Path(f"/proc/{pid}/comm").read_text().strip() != "sshd":
                os.kill(pid, signal.SIGKILL)


def keygen(path: Path) -> Path:
    subprocess.run(["ssh-keygen", "-q", "-t", "ed25519", "-N", "", "-f", str(path)], check=True)
    return path


def fingerprint_of(pub: Path) -> str:
    out = subprocess.run(["ssh-keygen", "-lf", str(pub)], capture_output=True, text=True, check=True).stdout
    return out.split()[1]


@contextmanager
def plain_user(client_key: Path) -> Iterator[tuple[str, Path]]:
    """A login user with passwordless sudo, as a lab gives its researchers: (name, home).

    The hosts' sshd also reads ``~/.ssh/authorized_keys``, where the client key goes. The
    account, its home (under /tmp: the test's own folders are root's alone) and its sudoers entry
    are removed on exit, after every process of the user is stopped.
    """
    name = f"fl{os.getpid()}"
    home = Path(f"/tmp/fogiac-{name}")
    sudoers = Path(f"/etc/sudoers.d/fogiac-test-{name}")
    subprocess.run(["useradd", "--create-home", "--home-dir", str(home), "--shell", "/bin/bash", name], check=True)
    try:
        subprocess.run(["usermod", "--password", "*", name], check=True)  # no password, yet not locked for sshd
        sudoers.write_text(f"{name} ALL=(ALL) NOPASSWD:ALL\n")
        sudoers.chmod(0o440)
        ssh_dir = home / ".ssh"
        ssh_dir.mkdir(mode=0o700)
        (ssh_dir / "authorized_keys").write_text(Path(f"{client_key}.pub").read_text())
        subprocess.run(["chown", "-R", f"{name}:{name}", str(ssh_dir)], check=True)
        yield name, home
    finally:
        _kill_owned_by(name)
        sudoers.unlink(missing_ok=True)
        subprocess.run(["userdel", name], capture_output=True)
        shutil.rmtree(home, ignore_errors=True)


def _kill_owned_by(user: str) -> None:
    """SIGKILL each process (by its id) whose real uid is ``user``'s: the account exists for one test only."""
    try:
        uid = pwd.getpwnam(user).pw_uid
    except KeyError:
        return
    for status in Path("/proc").glob("[0-9]*/status"):
        try:
            real = next(ln.split()[1] for ln in status.read_text().splitlines() if ln.startswith("Uid:"))
            if int(real) == uid:
                os.kill(int(status.parent.name), signal.SIGKILL)
        except (OSError, StopIteration, ValueError):
            continue


def _wait_port(address: str, port: int, timeout: float = 15.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            with socket.create_connection((address, port), timeout=0.5):
                return
        except OSError:
            time.sleep(0.05)
    raise RuntimeError(f"sshd on {address}:{port} did not come up")


_BLOCKS = 27  # blocks of nine /24s (one per host) in 10.232.0.0/16
_claim: tuple[int, IO[str]] | None = None


def _octet_base() -> int:
    """The first third octet of this process's block of nine /24s in 10.232.0.0/16.

    The gateway ends of the links sit in the root namespace, shared by every process on the machine,
    so concurrent test processes (pytest-xdist workers, other checkouts' runs) must not take the same
    block. Each process claims one with an exclusive lock on a file named after it, tried from the
    block its pid picks; the lock is held until the process exits (the kernel drops it even on SIGKILL).
    """
    global _claim
    if _claim is None:
        start = os.getpid() % _BLOCKS
        for step in range(_BLOCKS):
            block = (start + step) % _BLOCKS
            handle = open(Path(tempfile.gettempdir()) / f"fogiac-sshlab-block-{block}.lock", "w")
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                handle.close()
                continue
            _claim = (block * 9, handle)
            break
        else:
            raise RuntimeError(f"all {_BLOCKS} address blocks of 10.232.0.0/16 are held by other test processes")
    return _claim[0]


def gateway(index: int = 0) -> str:
    """This machine's address on host ``index``'s link: where the lab's own services (a package mirror)
    listen for its hosts. Known before the lab starts, so the hosts' login environment can name it."""
    return f"10.232.{_octet_base() + index}.1"


@contextmanager
def ssh_lab(root: Path, count: int, *, dead: int = 0,
            env: dict[str, str] | None = None) -> Iterator[tuple[list[LabHost], Path]]:
    """``count`` namespaces with sshd (plus ``dead`` ones without), and the client key path.

    ``env``: variables every SSH session on the hosts gets (sshd's ``SetEnv``), as a lab's own
    login configuration would set them.

    ``root`` holds keys, configs and each host's base folder; everything else is torn down on exit.
    """
    if count + dead > 9:
        raise ValueError("at most 9 hosts per lab")
    root.mkdir(parents=True, exist_ok=True)
    client_key = keygen(root / "client_key")
    Path("/run/sshd").mkdir(mode=0o755, exist_ok=True)  # sshd's privilege-separation folder
    with NetLab() as lab:
        hosts, daemons = [], []
        for i in range(count + dead):
            octet = _octet_base() + i
            ns = lab.namespace(f"h{i}")
            lab.link(None, ns, a_addr=f"{gateway(i)}/24", b_addr=f"10.232.{octet}.2/24")
            ns.add_route("default", via=gateway(i))
            address = f"10.232.{octet}.2"
            folder = root / f"h{i}"
            folder.mkdir(exist_ok=True)
            host_key = keygen(folder / "host_key")
            hosts.append(LabHost(name=f"h{i}", address=address, ns=ns, host_key_pub=Path(f"{host_key}.pub"),
                                 base_dir=folder / "base"))
            if i >= count:
                continue
            (folder / "authorized_keys").write_text(Path(f"{client_key}.pub").read_text())
            config = folder / "sshd_config"
            config.write_text(
                f"ListenAddress {address}\nPort 22\nHostKey {host_key}\nPidFile {folder}/sshd.pid\n"
                f"AuthorizedKeysFile {folder}/authorized_keys .ssh/authorized_keys\nPermitRootLogin prohibit-password\n"
                "PasswordAuthentication no\nKbdInteractiveAuthentication no\nUsePAM no\nStrictModes no\n"
                "MaxStartups 100\nMaxSessions 100\nSubsystem sftp internal-sftp\n"
                # one SetEnv line: sshd takes the first of repeated keywords
                + ("SetEnv " + " ".join(f'"{key}={value}"' for key, value in env.items()) + "\n" if env else "")
            )
            # Debian's bash sources ~/.bashrc for every SSH command; this machine's runs `pyenv init`
            # (~0.8 s). Real servers return early for non-interactive shells; so does this stand-in,
            # bind-mounted in sshd's private mount namespace (made by `ip netns exec`) only.
            (folder / "bashrc").write_text("# fogiac test host: non-interactive shells do nothing\n")
            start = f"mount --bind {folder / 'bashrc'} {Path.home() / '.bashrc'} 2>/dev/null; exec {SSHD} -D -e -f {config}"
            # Only the network namespace is the host's own: `ip netns exec` would also mount a fresh /sys
            # without this machine's cgroup hierarchies, where runc cannot start a container. A mount
            # namespace of its own keeps the bind mount above private to sshd.
            daemons.append(subprocess.Popen(
                ["nsenter", f"--net=/run/netns/{ns.name}", "unshare", "--mount", "--propagation", "private",
                 "sh", "-c", start], stdout=open(folder / "sshd.log", "w"), stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL, start_new_session=True, text=True))
        try:
            for host in hosts[:count]:
                _wait_port(host.address, 22)
            yield hosts, client_key
        finally:
            for daemon in daemons:  # reap sshd ourselves: a zombie looks alive to NetLab's cleanup
                daemon.terminate()
            for daemon in daemons:
                try:
                    daemon.wait(timeout=5)
                except subprocess.TimeoutExpired:
                    daemon.kill()
                    daemon.wait()
