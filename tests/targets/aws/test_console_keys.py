"""Host keys on aws are pinned from what the instance prints on its console, never trusted on sight."""

from __future__ import annotations

from typing import Any

import pytest

from fogiac.targets.aws.api import host_fingerprints, parse_host_fingerprints
from fogiac.errors import CloudError
from stacks.aws.compute import HOST_KEYS_BEGIN, HOST_KEYS_END

CONSOLE = f"""\
[   12.3] cloud-init[812]: Cloud-init v. 24.1 running 'modules:final'
{HOST_KEYS_BEGIN}
ssh-ed25519 AAAAC3NzaC1lZDI1NTE5AAAAIB4 root@ip-10-10-0-5
256 SHA256:Jq0H9v2S1Z0oV6vQ8m0n1mX0m5Yd8x9Yb2d0y8y4hHc root@ip-10-10-0-5 (ED25519)
ecdsa-sha2-nistp256 AAAAE2VjZHNh root@ip-10-10-0-5
256 SHA256:x1bXq7Yb2Q0W4vKqPp1m4wM3Xz9QfX1x0d8Q6Jt0bYk root@ip-10-10-0-5 (ECDSA)
{HOST_KEYS_END}
[   13.0] cloud-init[812]: finished
"""


def test_fingerprints_between_the_markers() -> None:
    assert parse_host_fingerprints(CONSOLE) == (
        "SHA256:Jq0H9v2S1Z0oV6vQ8m0n1mX0m5Yd8x9Yb2d0y8y4hHc",
        "SHA256:x1bXq7Yb2Q0W4vKqPp1m4wM3Xz9QfX1x0d8Q6Jt0bYk",
    )
    assert parse_host_fingerprints("boot log without markers SHA256:nope") == ()
    assert parse_host_fingerprints(CONSOLE.replace(HOST_KEYS_END, "")) == ()


class _Console:
    """The ec2 client seam: get_console_output answers from a script of outputs."""

    def __init__(self, outputs: list[str]) -> None:
        self.outputs, self.calls = outputs, 0

    def get_console_output(self, **kwargs: Any) -> dict[str, Any]:
        assert kwargs == {"InstanceId": "i-0abc", "Latest": True}
        self.calls += 1
        return {"Output": self.outputs.pop(0) if self.outputs else ""}


def test_waits_until_the_console_shows_the_keys() -> None:
    ec2 = _Console(["booting", "still booting", CONSOLE])
    found = host_fingerprints("i-0abc", region="us-west-2", ec2=ec2, poll=0, sleep=lambda s: None)
    assert len(found) == 2 and ec2.calls == 3


def test_refuses_when_no_keys_appear() -> None:
    with pytest.raises(CloudError, match=r"^i-0abc: no SSH host keys on its console after 0 s; refusing to connect"):
        host_fingerprints("i-0abc", region="us-west-2", ec2=_Console([]), timeout=0, sleep=lambda s: None)
