"""What the EC2 API itself knows, beyond fogiac's catalogue: botocore's region and instance-type lists.

botocore ships AWS's service model as data files: ``endpoints.json`` names every region of the
``aws`` partition and EC2's ``service-2.json.gz`` lists every ``InstanceType`` the API accepts.
A type or region there but not in the catalogue is real yet unpriced, so validation accepts it
with a warning instead of refusing the real world. The files are read directly (never
``import botocore``: ``fogiac validate`` imports no SDK) and only when a name misses the
catalogue, so the usual path pays nothing.
"""

from __future__ import annotations

import gzip
import json
import re
from functools import cache
from importlib.util import find_spec
from pathlib import Path

_KEY = b'"InstanceType":{'
_SHAPE = re.compile(rb'\{\s*"type"\s*:\s*"string"\s*,\s*"enum"\s*:\s*(\[[^\]]*\])')


def _data() -> Path | None:
    """botocore's data folder, found without importing botocore; None when it is not installed."""
    spec = find_spec("botocore")
    places = list(spec.submodule_search_locations or ()) if spec is not None else []
    return Path(places[0]) / "data" if places else None


@cache
def regions() -> frozenset[str]:
    """Every region of AWS's commercial partition that botocore knows; empty without botocore."""
    data = _data()
    if data is None or not (data / "endpoints.json").is_file():
        return frozenset()
    doc = json.loads((data / "endpoints.json").read_text())
    return frozenset(r for p in doc["partitions"] if p["partition"] == "aws" for r in p["regions"])


@cache
def instance_types() -> frozenset[str]:
    """Every instance type EC2's newest service model accepts; empty without botocore."""
    data = _data()
    versions = sorted((data / "ec2").glob("*/service-2.json*")) if data is not None else []
    if not versions:
        return frozenset()
    raw = versions[-1].read_bytes()
    raw = gzip.decompress(raw) if raw[:2] == b"\x1f\x8b" else raw
    at = raw.find(_KEY)  # one shape of a 4 MB document: find it rather than parse it all
    while at >= 0:
        found = _SHAPE.match(raw, at + len(_KEY) - 1)
        if found:
            return frozenset(json.loads(found.group(1)))
        at = raw.find(_KEY, at + 1)
    return frozenset()
