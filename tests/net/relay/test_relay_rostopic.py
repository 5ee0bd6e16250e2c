"""``relay.topics: auto`` serves ``rostopic echo`` (issue 26 item 29): rostopic learns the type from the
master before it subscribes, so the edge master must know a cloud topic's type while nobody subscribes yet.
Real roscores, the real relay ends, a rospy publisher in the cloud and the real ``rostopic`` command."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from fogiac.net.relay import TopicPolicy
from tests.net.relay.relay_support import Master, Procs
from tests.net.relay.test_relay_ros import relay_pair

pytestmark = [pytest.mark.ros, pytest.mark.skipif(shutil.which("rostopic") is None, reason="needs rostopic")]


def test_rostopic_echo_on_the_robot_gets_a_cloud_topic(masters: tuple[Master, Master], certs: Path,
                                                       procs: Procs) -> None:
    edge_m, cloud_m = masters
    with relay_pair(masters, certs, policy=TopicPolicy(auto=True)):
        procs.node(cloud_m, "pub", "/echo_chatter", "--forever", "--rate", "10", "--prefix", "hello")
        try:
            done = subprocess.run(["rostopic", "echo", "-n", "2", "/echo_chatter"], env=edge_m.env,
                                  capture_output=True, text=True, timeout=45)
        except subprocess.TimeoutExpired as err:
            pytest.fail(f"rostopic echo got nothing in 45 s: {err.stderr!r}")
        assert done.returncode == 0, done.stderr
        assert done.stdout.count('data: "hello') == 2, done.stdout
        # what it asked the edge master: the cloud publisher's real type
        assert ["/echo_chatter", "std_msgs/String"] in edge_m_types(edge_m)


def edge_m_types(master: Master) -> list[list[str]]:
    import xmlrpc.client
    return [list(t) for t in xmlrpc.client.ServerProxy(master.uri).getTopicTypes("/test")[2]]
