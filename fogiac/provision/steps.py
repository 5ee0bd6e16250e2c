"""The ordered, idempotent provisioning steps, one registry entry per name in ``HostSpec.steps``.

Each step looks before it acts and returns ``changed`` (it altered the host) or ``ok`` (the
host already matched). A second run over an unchanged plan therefore changes nothing, and the
report says "no changes".
"""

from __future__ import annotations

import hashlib
import tempfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from fogiac.errors import ProvisionError
from fogiac.hostmodel import Launching, Layout, NativeRos, Service, Where, master_uri
from fogiac.net import middleware
from fogiac.net.middleware import Deployment, Middleware
from fogiac.plan.model import HostSpec, Plan
from fogiac.provision import runtimes, venv
from fogiac.provision.host import Host, HostAccess, HostPorts, planned_ports, q
from fogiac.provision.managers import Manager, manager_for
from fogiac.provision.probe import Facts, gather
from fogiac.provision.runtimes.base import CHANGED as CHANGED
from fogiac.provision.runtimes.base import OK, SKIPPED, StepResult
from fogiac.provision.services import env_script, node_services
from fogiac.provision.sync import push_tree
from fogiac.registry import shipped_metadata
from fogiac.resources import package_dir

_CODE_IGNORE = ("tests/", "*.npz", "*.ipynb")  # the planner's problems (0.1 MB) and the grasp model (0.2 MB) go along


@dataclass(frozen=True)
class Options:
    """Caller's choices that hold for every host."""

    certs_dir: Path | None = None
    health_timeout: float = 30.0
    allow_install: bool = False
    dialed: Mapping[str, str] = field(default_factory=dict)  # host -> the address the edge dials it at
    revoked: tuple[str, ...] = ()  # a fleet's robots the record keeps revoked (refused by every host's link)


@dataclass
class HostRun:
    """One host's provisioning in progress: mutable because each step learns something
    (the runtime, the pushed workspaces' digests) that later steps use."""

    plan: Plan
    spec: HostSpec
    access: HostAccess
    host: Host
    options: Options
    runtime: runtimes.HostRuntime | None = None  # chosen by the runtime step
    engine: str = ""  # the container engine's command, on the container runtime
    images: dict[str, str] = field(default_factory=dict)  # node -> image tag built on the host
    venv_python: str = ""  # the virtual environment's interpreter (fogiac's code, native workload nodes)
    launch_bin: str = ""  # that environment's bin folder, when native launch nodes asked for requirements
    ros_image: str = ""  # the ROS image with what the middleware needs, when the plan's lacks it
    facts: Facts | None = None
    systemd: bool | None = None  # whether the runtime step's probe saw systemd as PID 1; None: not probed
    files_pushed: int = 0
    digests: dict[str, str] = field(default_factory=dict)
    ports: HostPorts | None = None  # what the host's services listen on, where the target chose; None: the plan's
    _manager: Manager | None = field(default=None, init=False, repr=False)

    @property
    def layout(self) -> Layout:
        return Layout(self.host.base, self.plan.stack)

    @property
    def manager(self) -> Manager:
        """Who keeps this host's services running, decided once per host."""
        if self._manager is None:
            self._manager = manager_for(self.host, systemd=self.systemd)
        return self._manager

    @property
    def chosen(self) -> runtimes.HostRuntime:
        """The host's runtime: native until the runtime step has chosen."""
        return self.runtime or runtimes.NATIVE

    @property
    def nodes_on_host(self) -> bool:
        """Nodes run from the host's python (their requirements in its venv): a chosen native runtime."""
        return self.runtime is not None and self.runtime.nodes_on_host

    def where(self) -> Where:
        code_root = self.layout.lib if self.access.ship_code else str(package_dir("fogiac").parent)
        ports = self.ports or planned_ports(self.plan)[self.spec.name]
        return Where(layout=self.layout, runtime=self.chosen, master_port=ports.master_port,
                         relay_port=ports.relay_port, ros_address=self.access.ros_address,
                         python=self.venv_python or self.access.python, code_root=code_root, user=self.access.user,
                         workspace_digests=tuple(sorted(self.digests.items())), engine=self.engine or "docker",
                         init=self.facts is not None and bool(self.engine) and self.engine in self.facts.inits,
                         images=tuple(sorted(self.images.items())),
                         workload_python=self.venv_python or self.access.python, launch_bin=self.launch_bin,
                         ros_image=self.ros_image)

    @property
    def carrier(self) -> Middleware:
        return middleware.get(self.plan.middleware)

    @property
    def deploying(self) -> Deployment:
        return middleware.deployment(self.plan.middleware)

    @property
    def allow_install(self) -> bool:
        return self.options.allow_install

    @property
    def native_ros(self) -> NativeRos:
        return self.deploying.native_ros(self.plan.ros_distro)

    @property
    def launching(self) -> Launching:
        return self.carrier.launching

    def env_text(self) -> str:
        """The env file every service script on the host sources (the distro's setup, the middleware's env)."""
        return env_script(self.deploying.node_env(self.where()), host=self.spec.name,
                          setup=self.runtime.env_setup(self.native_ros) if self.runtime is not None else "")

    @property
    def dialed(self) -> str:
        """The address the edge reaches this host at: the target's word (a private VPC address over the
        VPN), else the one provisioning reaches it at."""
        return self.options.dialed.get(self.spec.name) or self.access.location.rsplit(":", 1)[0].rpartition("@")[2]

    def services(self) -> tuple[Service, ...]:
        """The middleware's host services (a ROS master, a router), then one per node."""
        where = self.where()
        first = self.deploying.host_services(self.plan, self.spec, where, certs=self.options.certs_dir)
        return first + node_services(self.plan, self.spec, where)

    def credentials(self) -> bool:
        """The middleware's credentials made on the host (its key never leaves it); True when they changed."""
        certs = self.options.certs_dir
        return certs is not None and self.deploying.host_credentials(
            self.host, python=self.where().python, folder=self.layout.certs, certs_dir=certs, plan=self.plan,
            spec=self.spec, dialed=self.dialed)

    def link_services(self) -> tuple[Service, ...]:
        """What joins the host to the edge after its nodes (none without certificates or fogiac's code)."""
        if self.options.certs_dir is None or not link_available(self):
            return ()
        return self.deploying.link_services(self.plan, self.spec, self.where())


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def put_unless_same(host: Host, data: bytes, remote: str, *, mode: int, known: str | None = None) -> bool:
    """Put ``data`` at ``remote`` unless the host already has exactly it (``known``: its sha256 there, if the
    caller has it; else asked); True if it wrote."""
    if known is None:
        known = (host.run(f"sha256sum {q(remote)} 2>/dev/null", check=False).stdout.split() or [""])[0]
    if known == _sha(data):
        return False
    host.put(data, remote, mode=mode)
    return True


def ensure_file(run: HostRun, data: bytes, remote: str, *, mode: int = 0o644) -> bool:
    """Put ``data`` at ``remote`` unless the host already has exactly it; True if it wrote."""
    wrote = put_unless_same(run.host, data, remote, mode=mode,
                            known=run.facts.sha(remote) if run.facts is not None else None)
    run.files_pushed += wrote
    return wrote


def step_connect(run: HostRun) -> StepResult:
    attempts = run.host.connect()
    return OK, f"reached in {attempts} attempt{'s' if attempts != 1 else ''}"


def step_runtime(run: HostRun) -> StepResult:
    host, layout, changes = run.host, run.layout, []
    facts = run.facts = gather(host, layout, link_program=_link_program(run), engines=runtimes.engines(run.spec))
    if facts.missing:
        host.run(f"mkdir -p -m 700 {' '.join(q(f) for f in facts.missing)}")
        changes.append("folders")
    run.systemd = "systemd" in facts.flags
    run.runtime, run.engine = runtimes.choose(run.spec, facts)
    changes += run.runtime.prepare(run, facts)
    if ensure_file(run, Path(__file__).with_name("supervise.py").read_bytes(), layout.supervisor, mode=0o755):
        changes.append("supervisor")
    if run.access.ship_code:
        for package in ("fogiac", "workloads"):
            dest = f"{layout.lib}/{package}"
            pushed = push_tree(host, package_dir(package), dest, tmp_dir=layout.tmp, extra_ignore=_CODE_IGNORE,
                               remote_sums=facts.sums(f"{dest}.sha256sums"))
            run.files_pushed += pushed.files
            if pushed.changed:
                changes.append(f"{package} code")
        if _push_metadata(run, facts):
            changes.append("fogiac metadata")
        program = run.deploying.link_program
        if program and (package_dir("fogiac").parent / program).is_file():
            facts.flags.add("linkprogram")  # pushed just now: the probe ran before the first push
    detail = f"{run.runtime.name} ROS" + (f"; {', '.join(changes)}" if changes else "")
    return (CHANGED if changes else OK), detail


def _push_metadata(run: HostRun, facts: Facts) -> bool:
    """fogiac's ``dist-info`` beside its copied code, so the host's ``python -m fogiac`` finds its plug-ins
    (entry points) as an installed fogiac would; True when it changed."""
    name, files = shipped_metadata()
    with tempfile.TemporaryDirectory() as tmp:
        for file, text in files.items():
            (Path(tmp) / file).write_text(text)
        dest = f"{run.layout.lib}/{name}"
        pushed = push_tree(run.host, Path(tmp), dest, tmp_dir=run.layout.tmp,
                           remote_sums=facts.sums(f"{dest}.sha256sums"))
    run.files_pushed += pushed.files
    return pushed.changed


def _link_program(run: HostRun) -> str:
    """Where the middleware's link program (:attr:`Deployment.link_program`) is on the host; '' for none."""
    program = run.deploying.link_program
    if not program:
        return ""
    code_root = run.layout.lib if run.access.ship_code else str(package_dir("fogiac").parent)
    return f"{code_root}/{program}"


def step_images(run: HostRun) -> StepResult:
    """Build each workload or ``build:`` node's image on the host, where the runtime has images."""
    return run.chosen.build_images(run)


def _launch_requirements(run: HostRun) -> tuple[str, ...]:
    """What the launch packages on a native host ask for in their requirements files, each once."""
    if not run.nodes_on_host:
        return ()  # a container host installs them in the node's image
    found: list[str] = []
    for node in (run.plan.node(x) for x in run.spec.nodes):
        if node.launch is not None and node.launch.requirements is not None:
            found += [r for r in venv.file_requirements(node.launch.requirements) if r not in found]
    return tuple(found)


def step_venv(run: HostRun) -> StepResult:
    """A host that runs fogiac's pushed code gets fogiac's requirements and its middleware's (the relay's
    cloud end, the Zenoh router import them) in a venv over the system's python3, in either runtime (they
    run on the host), plus its workload nodes' on a native host; launch packages' own requirements go in
    the same venv, whose bin folder leads their nodes' PATH."""
    launch = _launch_requirements(run)
    if not run.access.ship_code and not launch:
        return SKIPPED, "fogiac's code runs on its own interpreter"
    names = [n.workload for n in (run.plan.node(x) for x in run.spec.nodes) if n.workload is not None]
    reqs = venv.requirements(names if run.nodes_on_host else [], fogiac=True,
                             middleware=run.carrier.host_requirements) if run.access.ship_code else ()
    reqs += tuple(r for r in launch if r not in reqs)
    marker = f"{run.layout.state}/venv.sha256"
    known = run.facts.marker(marker) if run.facts is not None else ""
    env = venv.ensure(run.host, root=f"{run.layout.base}/venv", marker=marker, known=known, reqs=reqs,
                      python=run.access.python, allow_install=run.options.allow_install,
                      log=f"{run.layout.run}/venv-install.log")
    if run.access.ship_code:
        run.venv_python = env.python
    if launch:
        run.launch_bin = env.python.rsplit("/", 1)[0]
    return (CHANGED, f"installed {', '.join(reqs)}") if env.built else \
        (OK, f"requirements installed already ({env.digest[:12]})")


def _workspaces(run: HostRun) -> list[str]:
    seen: list[str] = []
    for name in run.spec.nodes:
        launch = run.plan.node(name).launch
        if launch is not None and launch.workspace not in seen:
            seen.append(launch.workspace)
    return seen


def step_workspace(run: HostRun) -> StepResult:
    sent, files, removed = 0, 0, 0
    for local in _workspaces(run):
        dest = run.layout.workspace(local)
        known = run.facts.sums(f"{dest}.sha256sums") if run.facts is not None else None
        pushed = push_tree(run.host, Path(local), dest, tmp_dir=run.layout.tmp, remote_sums=known)
        run.digests[local] = pushed.digest
        sent, files, removed = sent + pushed.bytes_sent, files + pushed.files, removed + pushed.removed
    run.files_pushed += files
    if not files and not removed:
        return OK, "workspace up to date"
    return CHANGED, f"pushed {files} file(s), {sent} bytes; removed {removed}"


def step_env_script(run: HostRun) -> StepResult:
    """Run each workspace's env scripts (and its build: catkin_make, colcon) once per content hash."""
    ran = []
    for local in _workspaces(run):
        scripts = sorted({n.launch.env_script for n in (run.plan.node(x) for x in run.spec.nodes)
                          if n.launch and n.launch.workspace == local and n.launch.env_script})
        bodies = [Path(s).read_bytes() for s in scripts]
        key = _sha(b"\0".join([run.digests.get(local, "").encode(), *bodies]))
        dest = run.layout.workspace(local)
        marker = f"{run.layout.state}/setup-{dest.rsplit('/', 1)[-1]}.sha256"
        done = (run.facts.marker(marker) if run.facts is not None
                else run.host.run(f"cat {q(marker)} 2>/dev/null", check=False).stdout.strip())
        if done == key:
            continue
        run.chosen.set_up_workspace(run, local=local, dest=dest, bodies=bodies)
        run.host.put(key.encode() + b"\n", marker, mode=0o600)
        ran.append(Path(local).name)
    return (CHANGED, f"set up {', '.join(ran)}") if ran else (OK, "set up already")


def step_services(run: HostRun) -> StepResult:
    env_changed = ensure_file(run, run.env_text().encode(), run.layout.env_file)
    manager = run.manager
    wanted = run.services()
    made = run.carrier.credentials_first and run.credentials()  # a new certificate: its router restarts
    for service in wanted:
        for path, text, mode in service.files:
            ensure_file(run, text.encode(), path, mode=mode)
    started = manager.ensure(run.host, run.layout, wanted, restart_all=env_changed or made, facts=run.facts)
    kept = [s.name for s in wanted + run.deploying.link_services(run.plan, run.spec, run.where())]
    stopped = manager.prune(run.host, run.layout, keep=kept, facts=run.facts)
    if not started and not stopped and not env_changed:
        return OK, f"{len(wanted)} service(s) running ({manager.name})"
    parts = [f"started {', '.join(started)}"] if started else []
    parts += [f"stopped {', '.join(stopped)}"] if stopped else []
    return CHANGED, "; ".join(parts or ["ROS environment updated"]) + f" ({manager.name})"


def link_available(run: HostRun) -> bool:
    """Whether the host has what the middleware's link services run (its :attr:`Deployment.link_program`)."""
    program = _link_program(run)
    if not program:
        return True
    if run.facts is not None:
        return "linkprogram" in run.facts.flags
    return run.host.run(f"test -f {q(program)}", check=False).ok


def step_link(run: HostRun) -> StepResult:
    """The middleware's link to the edge, after the nodes (its :meth:`Deployment.link_services`: the relay's
    cloud end and its watchdog, say); the step is the same for every middleware, which it only asks."""
    certs = run.options.certs_dir
    if certs is None:
        return SKIPPED, "no certificates given"
    # A fleet's access rules: before the link starts (it never runs without them), and never a restart when
    # they change (the link re-reads them), so a robot added or revoked leaves the host's processes alone. Also
    # where the host's services carry the link (a Zenoh router follows its fleet file).
    for name, data, mode in middleware.fleet_files(run.plan.middleware, run.plan, run.spec,
                                                   revoked=run.options.revoked):
        ensure_file(run, data, f"{run.layout.certs}/{name}", mode=mode)
    wanted = run.deploying.link_services(run.plan, run.spec, run.where())
    if not wanted:
        return OK, "the host's services carry the link"
    changed = [name for name, mode in run.deploying.link_files()
               if ensure_file(run, (certs / name).read_bytes(), f"{run.layout.certs}/{name}", mode=mode)]
    if not link_available(run):
        for service in wanted:
            ensure_file(run, service.script.encode(), f"{run.layout.services}/{service.name}.sh", mode=0o700)
        return SKIPPED, "fogiac's code is not on the host; service scripts rendered only"
    made = not run.carrier.credentials_first and run.credentials()
    started = run.manager.ensure(run.host, run.layout, wanted, restart_all=bool(changed) or made, facts=run.facts)
    what = " and ".join(s.name for s in wanted)
    return (CHANGED, f"{what} started") if started or changed else (OK, f"{what} running")


def step_health(run: HostRun) -> StepResult:
    checks = list(run.services()) + list(run.link_services())
    results = run.manager.health(run.host, run.layout, checks, master=master_uri(run.where()),
                                timeout=run.options.health_timeout)
    bad = [f"{name} unhealthy: {detail}" for name, ok, detail in results if not ok]
    if bad:
        raise ProvisionError(f"{run.spec.name}: {'; '.join(bad)}")
    kinds = {s.name: s.check for s in checks}
    details = [f"{name.removeprefix('node-')}: {detail}" for name, _, detail in results
               if kinds.get(name) in ("node", "any")]
    return OK, "; ".join(details) or "all services up"


STEPS: dict[str, Callable[[HostRun], StepResult]] = {
    "connect": step_connect,
    "runtime": step_runtime,
    "images": step_images,
    "venv": step_venv,
    "workspace": step_workspace,
    "env_script": step_env_script,
    "services": step_services,
    "link": step_link,
    "health": step_health,
}


def step(name: str) -> Callable[[HostRun], StepResult]:
    try:
        return STEPS[name]
    except KeyError:
        raise ProvisionError(f"unknown provisioning step {name!r}; valid: {', '.join(STEPS)}") from None
