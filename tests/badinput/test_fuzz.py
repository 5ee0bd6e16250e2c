"""Hypothesis over the two parsers hostile input reaches first: the relay's frame decoder (and
the codecs behind DATA frames) and the manifest loader. Whatever the bytes, the answer is frames
or a FrameError, a Manifest or one-line ManifestError problems; never anything else."""

from __future__ import annotations

import struct

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fogiac.errors import ManifestError
from fogiac.manifest.schema import Manifest, parse_manifest
from fogiac.net.relay import framing
from fogiac.net.relay.compression import codec
from fogiac.net.relay.framing import FrameError, Kind

FRAME_EXAMPLES = 3000
MANIFEST_EXAMPLES = 1500

# Mostly well-formed headers with hostile lengths and kinds, then arbitrary tails.
headers = st.builds(lambda n, k, t: struct.pack("!IBI", n, k, t),
                    st.one_of(st.integers(0, 64), st.integers(0, 2**32 - 1)), st.integers(0, 255),
                    st.integers(0, 2**32 - 1))
streams = st.lists(st.one_of(headers, st.binary(max_size=64)), max_size=6).map(b"".join)


@settings(max_examples=FRAME_EXAMPLES, deadline=None)
@given(streams)
def test_frame_decoder_yields_frames_or_a_frame_error(data: bytes) -> None:
    try:
        for frame in framing.decode_stream(data):
            assert isinstance(frame.kind, Kind) and len(frame.payload) <= framing.MAX_FRAME
            if frame.kind in (Kind.HELLO, Kind.STATE, Kind.SUBSCRIBE, Kind.OPEN):
                framing.parse_json(frame)
            elif frame.kind is Kind.DATA:
                framing.split_data(frame.payload)
            elif frame.kind is Kind.PING:
                framing.parse_ping(frame)
            elif frame.kind is Kind.PONG:
                framing.parse_pong(frame)
    except FrameError:
        pass


@settings(max_examples=FRAME_EXAMPLES, deadline=None)
@given(st.sampled_from(["zstd", "lz4"]), st.one_of(
    st.binary(max_size=200),
    st.sampled_from([b"\x28\xb5\x2f\xfd", b"\x04\x22\x4d\x18"]).flatmap(lambda magic: st.binary(max_size=64).map(
        lambda tail: magic + tail)),
))
def test_decompressing_peer_bytes_yields_bytes_or_a_frame_error(name: str, body: bytes) -> None:
    try:
        out = codec(name).decompress(body)
    except FrameError:
        return
    assert len(out) <= framing.MAX_FRAME


yaml_bits = st.sampled_from([
    "name: x\n", "nodes:\n", "  - ", "{name: a, machine: t3.micro, image: i}\n", "&a ", "*a", "<<: ", "[", "]",
    "{", "}", ": ", "- ", "\n", "  ", "'", '"', "!!python/object:os.system ", "\t", "\x00", "\x07", "#", "?",
    "cloud: {provider: hosts, hosts: [{name: h, address: ", "lab_pc", "}]}\n", "ssh_from: [0.0.0.0/1]\n",
    "network:\n  ", "relay: {compression: {", "/a: zstd", "\u2028", "\ufeff", "%YAML 1.1\n", "---\n", "...\n",
])
manifests = st.one_of(st.lists(yaml_bits, max_size=30).map("".join), st.text(max_size=300))


@settings(max_examples=MANIFEST_EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(manifests)
def test_manifest_loader_gives_a_manifest_or_one_line_problems(text: str) -> None:
    try:
        assert isinstance(parse_manifest(text, source="fuzz.yaml"), Manifest)
    except ManifestError as err:
        assert err.problems
        for line in err.problems:
            assert line.startswith("fuzz.yaml:") and "\n" not in line, line
