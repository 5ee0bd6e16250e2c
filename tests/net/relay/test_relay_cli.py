"""``fogiac certs`` and the relay commands' argument errors (no ROS needed)."""

from __future__ import annotations

import stat
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.net.relay.config import parse_hostport, policy_from_spec
from fogiac.net.relay.errors import RelayError
from fogiac.net.relay.graph import TopicPolicy
from fogiac.net.relay.tls import expected_server_name

runner = CliRunner()


def test_certs_writes_a_bundle_with_private_keys_and_prints_no_key(tmp_path: Path) -> None:
    result = runner.invoke(app, ["certs", str(tmp_path / "c"), "--stack", "lab"])
    assert result.exit_code == 0, result.output
    assert "PRIVATE KEY" not in result.output
    for key in ("ca.key", "server.key", "client.key"):
        assert stat.S_IMODE((tmp_path / "c" / key).stat().st_mode) == 0o600
    assert expected_server_name(tmp_path / "c") == "server.relay.lab.fogiac"
    again = runner.invoke(app, ["certs", str(tmp_path / "c")])
    assert again.exit_code == 1
    assert "already holds a CA (ca.key); pick another directory" in again.output


def test_edge_rejects_unknown_compression(tmp_path: Path) -> None:
    runner.invoke(app, ["certs", str(tmp_path)])
    result = runner.invoke(app, ["relay", "edge", "--connect", "127.0.0.1:1", "--certs", str(tmp_path),
                                 "--compression", "/a=gzip"])
    assert result.exit_code == 1
    assert "unknown compression 'gzip'; valid: lz4, none, zstd" in result.output


def test_missing_certificates_are_named(tmp_path: Path) -> None:
    result = runner.invoke(app, ["relay", "cloud", "--listen", "127.0.0.1:0", "--certs", str(tmp_path)])
    assert result.exit_code == 1
    assert f"certificate directory {tmp_path} lacks ca.pem, server.pem, server.key" in result.output


def test_topic_specs() -> None:
    assert policy_from_spec("auto") == TopicPolicy(auto=True)
    assert policy_from_spec("/a,/b", out_topics="/c") == TopicPolicy(topics=("/a", "/b"), out_topics=("/c",))
    with pytest.raises(RelayError, match=r"topic names must be absolute \(start with '/'\): b"):
        policy_from_spec("/a,b")
    assert parse_hostport("10.0.0.5") == ("10.0.0.5", 11411)
    assert parse_hostport("[::1]:9") == ("::1", 9)
    with pytest.raises(RelayError, match="'h:x' is not HOST:PORT"):
        parse_hostport("h:x")
