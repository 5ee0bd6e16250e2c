"""Per-topic compression codecs, keyed by name (the manifest says ``zstd`` or ``lz4``).

Codecs are imported lazily so ``none`` costs nothing; an unknown name raises an error that
lists the valid ones.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from fogiac.errors import RelayError


@dataclass(frozen=True)
class Codec:
    name: str
    compress: Callable[[bytes], bytes]
    decompress: Callable[[bytes], bytes]


def _same(data: bytes) -> bytes:
    return data


def _none() -> Codec:
    return Codec("none", _same, _same)


def _zstd() -> Codec:
    import zstandard

    # zstd's default level 3: >= 2x on noisy 16-bit depth at < 5 ms CPU per 640x480 frame
    # (level 1 is ~2x faster but only 1.75x on that worst case; see benchmarks/relay).
    comp = zstandard.ZstdCompressor(level=3)
    dctx = zstandard.ZstdDecompressor()

    def decompress(data: bytes) -> bytes:
        return dctx.decompress(data)

    return Codec("zstd", comp.compress, decompress)


def _lz4() -> Codec:
    import lz4.frame

    return Codec("lz4", lz4.frame.compress, lz4.frame.decompress)


CODECS: dict[str, Callable[[], Codec]] = {"none": _none, "zstd": _zstd, "lz4": _lz4}


def check_name(name: str) -> str:
    if name not in CODECS:
        raise RelayError(f"unknown compression {name!r}; valid: {', '.join(sorted(CODECS))}")
    return name


def codec(name: str) -> Codec:
    """A fresh codec (zstd contexts are not thread-safe, so each topic gets its own)."""
    return CODECS[check_name(name)]()


def parse_spec(spec: str) -> tuple[str, dict[str, str]]:
    """``"zstd"`` or ``"/a=zstd,/b=lz4"`` or a mix -> (default, per-topic overrides)."""
    default = "none"
    per_topic: dict[str, str] = {}
    for item in filter(None, (part.strip() for part in spec.split(","))):
        topic, sep, name = item.rpartition("=")
        if sep:
            per_topic[topic] = check_name(name)
        else:
            default = check_name(name)
    return default, per_topic
