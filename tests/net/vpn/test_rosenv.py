"""The ROS environment of a side: the dict and the sourced env.sh agree."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from fogiac.net.rosenv import side_env


def test_ip_address_side() -> None:
    env = side_env(side="edge", master_uri="http://10.200.0.2:11311/", address="10.200.0.2")
    assert dict(env.env) == {"ROS_MASTER_URI": "http://10.200.0.2:11311/", "ROS_IP": "10.200.0.2"}
    assert env.text == (
        "# fogiac: ROS 1 environment of the edge side. Source it: . env.sh\n"
        "export ROS_MASTER_URI=http://10.200.0.2:11311/\n"
        "export ROS_IP=10.200.0.2\n"
        "unset ROS_HOSTNAME\n"
    )


def test_host_name_side_uses_ros_hostname() -> None:
    env = side_env(side="cloud gpu", master_uri="http://gpu-1.internal:11311", address="gpu-1.internal")
    assert dict(env.env) == {"ROS_MASTER_URI": "http://gpu-1.internal:11311",
                             "ROS_HOSTNAME": "gpu-1.internal"}
    assert "export ROS_HOSTNAME=gpu-1.internal\nunset ROS_IP\n" in env.text


def test_sourcing_env_sh_gives_the_same_values(tmp_path: Path) -> None:
    env = side_env(side="cloud", master_uri="http://10.231.2.10:11311", address="10.231.2.10")
    script = tmp_path / "env.sh"
    script.write_text(env.text)
    out = subprocess.run(
        ["sh", "-c", f'ROS_HOSTNAME=stale; . {script}; echo "$ROS_MASTER_URI|$ROS_IP|${{ROS_HOSTNAME-unset}}"'],
        capture_output=True, text=True, check=True,
    ).stdout
    assert out == "http://10.231.2.10:11311|10.231.2.10|unset\n"


@pytest.mark.parametrize(
    ("uri", "address", "message"),
    [
        ("10.0.0.1:11311", "10.0.0.1", r"^ROS master URI '10.0.0.1:11311' is not of the form http://HOST:PORT/$"),
        ("http://10.0.0.1", "10.0.0.1", r"^ROS master URI 'http://10.0.0.1' is not of the form"),
        ("http://10.0.0.1:11311", "a b", r"^'a b' is neither an IP address nor a host name$"),
    ],
)
def test_bad_values_are_bugs(uri: str, address: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        side_env(side="edge", master_uri=uri, address=address)
