"""The container path, checked on its exact text: no Docker engine or systemd runs here."""

from __future__ import annotations

from pathlib import Path

import pytest

from fogiac.plan.compile import compile_plan
from fogiac.errors import ProvisionError
from fogiac.manifest.schema import parse_manifest
from fogiac.net import middleware
from fogiac.net.relay import services as relay_svc
from fogiac.plan.model import Plan
from fogiac.provision import services as svc

MANIFEST = """
name: fleet
cloud: {provider: aws, region: us-west-2}
nodes:
  - name: talker
    machine: t3.small
    image: ros:noetic-ros-core
    command: [rostopic, pub, -r, "1", /chatter, std_msgs/String, "data: hello"]
    env: {FOO: bar}
  - name: grasp
    machine: g4dn.xlarge
    gpu: true
    image: example/grasp:1.2
  - name: plan
    machine: c5.xlarge
    workload: motion_planning
  - name: arm
    machine: t3.small
    launch: {package: fogtest, file: talker.launch, workspace: ws}
"""


@pytest.fixture
def plan(tmp_path: Path) -> Plan:
    (tmp_path / "ws").mkdir()
    return compile_plan(parse_manifest(MANIFEST, base=tmp_path))


def _where(runtime: str, base: str = "/home/ubuntu/.fogiac/fleet-dev/x") -> svc.Where:
    return svc.Where(layout=svc.Layout(base), runtime=runtime, master_port=11311, relay_port=11411,
                     ros_address="10.10.0.5", python="python3", code_root=f"{base}/lib", user="ubuntu",
                     images=(("plan", "fogiac/motion_planning:0123456789abcdef"),))


RUN = "docker run --rm --network host --label fogiac.stack=fleet-dev --label fogiac.host={host}"
ROS = "--env ROS_MASTER_URI=http://127.0.0.1:11311 --env ROS_IP=127.0.0.1"  # loopback: only the relay faces out


def _line(plan: Plan, node: str) -> str:
    spec = plan.host(node)
    return svc.docker_run(plan.node(node), plan=plan, spec=spec, where=_where(svc.CONTAINER))


def test_cpu_image_node_runs_without_gpu_flags(plan: Plan) -> None:
    env_file = _where(svc.CONTAINER).layout.env + "/node-talker.env"
    assert _line(plan, "talker") == (
        f"{RUN.format(host='talker')} --name fogiac-fleet-dev-talker {ROS} --env-file {env_file} "
        "-- ros:noetic-ros-core rostopic pub -r 1 /chatter std_msgs/String 'data: hello'"
    )


def test_node_env_goes_through_a_private_file_not_the_command_line(plan: Plan) -> None:
    where = _where(svc.CONTAINER)
    (service,) = svc.node_services(plan, plan.host("talker"), where)
    assert service.files == ((f"{where.layout.env}/node-talker.env", "FOO=bar\n", 0o600),)
    assert "bar" not in service.script.replace("sha256", "")
    assert svc.env_file_text((("A", "x y='z'"),)) == "A=x y='z'\n"
    with pytest.raises(ProvisionError, match=r"^env A: a value cannot hold a line break$"):
        svc.env_file_text((("A", "one\ntwo"),))


def test_gpu_types_get_gpus_all(plan: Plan) -> None:
    # No GPU on these machines: --gpus all is checked as text.
    assert _line(plan, "grasp") == (
        f"{RUN.format(host='grasp')} --gpus all --name fogiac-fleet-dev-grasp {ROS} -- example/grasp:1.2"
    )


def test_launch_node_mounts_its_pushed_workspace_read_only(plan: Plan) -> None:
    ws = _where(svc.CONTAINER).layout.workspace(plan.node("arm").launch.workspace)  # type: ignore[union-attr]
    assert _line(plan, "arm") == (
        f"{RUN.format(host='arm')} --name fogiac-fleet-dev-arm {ROS} --env ROS_PACKAGE_PATH=/fogiac/ws/src:/fogiac/ws "
        f"--volume {ws}:/fogiac/ws:ro --workdir /fogiac/ws -- ros:noetic-ros-core bash -c "
        "'if [ -f /fogiac/ws/devel/setup.bash ]; then . /fogiac/ws/devel/setup.bash; fi; "
        "exec roslaunch --wait \"$0\" \"$1\"' fogtest talker.launch"
    )


def test_workload_node_runs_its_image(plan: Plan) -> None:
    assert _line(plan, "plan") == (
        f"{RUN.format(host='plan')} --name fogiac-fleet-dev-plan {ROS} -- fogiac/motion_planning:0123456789abcdef "
        "python -m workloads.motion_planning node"
    )


def test_container_service_script_and_systemd_unit(plan: Plan) -> None:
    where = _where(svc.CONTAINER)
    (service,) = svc.node_services(plan, plan.host("grasp"), where)
    base = where.layout.base
    assert service.name == "node-grasp" and service.check == "any"
    assert service.script.splitlines()[-2:] == [
        "docker rm -f fogiac-fleet-dev-grasp >/dev/null 2>&1 || true",
        "exec " + _line(plan, "grasp"),
    ]
    assert f". {base}/env/ros.sh" in service.script.splitlines()
    assert service.unit == (
        "# fogiac service node-grasp on host grasp (stack fleet-dev): rendered by fogiac, edits are overwritten.\n"
        "[Unit]\nDescription=fogiac fleet-dev: node-grasp\n"
        "After=network-online.target fogiac-fleet-dev-ros-master.service\nWants=network-online.target\n\n"
        "[Service]\nType=simple\nUser=ubuntu\n"
        f"ExecStart=/bin/bash {base}/services/node-grasp.sh\n"
        "Restart=on-failure\nRestartSec=2\nTimeoutStopSec=15\nKillMode=control-group\n\n"
        "[Install]\nWantedBy=multi-user.target\n"
    )


def test_ros_master_runs_from_the_official_image_on_container_hosts(plan: Plan) -> None:
    master = relay_svc.master_service(plan, plan.host("talker"), _where(svc.CONTAINER))
    assert master.script.splitlines()[-1] == (
        f"exec {RUN.format(host='talker')} --name fogiac-fleet-dev-talker-ros-master {ROS} "
        "-- ros:noetic-ros-core roscore -p 11311"
    )
    gpu_master = relay_svc.master_service(plan, plan.host("grasp"), _where(svc.CONTAINER))
    assert "--gpus" not in gpu_master.script


def test_native_hosts_run_roslaunch_and_workloads_directly(plan: Plan) -> None:
    where = _where(svc.NATIVE)
    (arm,) = svc.node_services(plan, plan.host("arm"), where)
    ws = where.layout.workspace(plan.node("arm").launch.workspace)  # type: ignore[union-attr]
    assert arm.script.splitlines()[-3:] == [
        f"export ROS_PACKAGE_PATH={ws}/src:{ws}${{ROS_PACKAGE_PATH:+:$ROS_PACKAGE_PATH}}",
        f"cd {ws}",
        "exec roslaunch --wait fogtest talker.launch",
    ]
    (workload,) = svc.node_services(plan, plan.host("plan"), where)
    assert workload.script.splitlines()[-1] == "exec python3 -m workloads.motion_planning node"
    assert f"export PYTHONPATH={where.code_root}${{PYTHONPATH:+:$PYTHONPATH}}" in workload.script


def test_an_image_node_on_a_host_without_docker_is_a_clear_error(plan: Plan) -> None:
    with pytest.raises(ProvisionError, match=r"^talker: node talker runs image ros:noetic-ros-core but the host has "
                                             r"no working container engine \(`docker info` failed\)"):
        svc.node_services(plan, plan.host("talker"), _where(svc.NATIVE))


def test_relay_cloud_end_command(plan: Plan) -> None:
    where = _where(svc.NATIVE)
    relay = relay_svc.relay_service(plan, plan.host("talker"), where)
    assert relay.script.splitlines()[-1] == (
        "exec python3 -m fogiac relay cloud --listen 0.0.0.0:11411 --master http://127.0.0.1:11311 "
        f"--certs {where.layout.certs} --ros-host 127.0.0.1 --stats-file {where.layout.run}/relay-cloud.stats.json "
        "--topics auto"  # the edge's policy; its ROS side on loopback beside the host's master
    )


def test_autostop_watchdog_reads_the_relay_stats(plan: Plan) -> None:
    where = _where(svc.NATIVE)
    watchdog = next(s for s in middleware.deployment(plan.middleware).link_services(plan, plan.host("talker"), where)
                    if s.name == "autostop")
    assert plan.autostop is not None
    assert watchdog.script.splitlines()[-1] == (
        f"exec python3 -m fogiac.provision.autostop --stats {where.layout.run}/relay-cloud.stats.json "
        f"--run {where.layout.run} --idle-s {plan.autostop.idle_s:g} --action {plan.autostop.action} "
        f"--power {plan.autostop.power}"
    )


def test_a_ros2_nodes_unit_starts_after_its_hosts_zenoh_router_not_a_master(tmp_path: Path) -> None:
    text = ("name: fleet\nros: {distro: jazzy}\ncloud: {provider: aws, region: us-west-2}\nnodes:\n"
            "  - name: talker\n    machine: t3.small\n    image: ros:jazzy-ros-core\n"
            "    command: [ros2, topic, pub, /chatter, std_msgs/msg/String, 'data: hi']\n    topics: {out: [/chatter]}\n")
    plan = compile_plan(parse_manifest(text, base=tmp_path))
    (service,) = svc.node_services(plan, plan.host("talker"), _where(svc.CONTAINER))
    assert "After=network-online.target fogiac-fleet-dev-zenoh-router.service\n" in service.unit
    assert "ros-master" not in service.unit


def test_an_engine_with_an_init_runs_every_container_under_it(plan: Plan) -> None:
    """`--init`: the engine's init is PID 1 and passes a stop's SIGTERM on to the node, which as PID 1 would ignore
    it (down then waited out the engine's stop timeout, and a kill, for every container)."""
    import dataclasses

    where = dataclasses.replace(_where(svc.CONTAINER), init=True)
    spec = plan.host("plan")
    assert svc.docker_run(plan.node("plan"), plan=plan, spec=spec, where=where) == _line(plan, "plan").replace(
        "docker run --rm --network host", "docker run --rm --init --network host")
    master = relay_svc.master_service(plan, spec, where)
    assert " run --rm --init --network host " in master.script, master.script
