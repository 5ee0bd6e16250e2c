"""Random edits of a valid manifest give a Manifest or ManifestError lines, never anything else."""

from __future__ import annotations

import copy
from typing import Any

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fogiac.errors import ManifestError
from fogiac.manifest.schema import Manifest, parse_manifest

from .conftest import EXAMPLES

BASE = yaml.safe_load((EXAMPLES / "grasp-planning.yaml").read_text())

scalars = st.one_of(
    st.none(), st.booleans(), st.integers(-5, 70000), st.floats(allow_nan=False),
    st.text(max_size=12), st.sampled_from(["auto", "zstd", "10.0.0.0/8", "g4dn.xlarge", "/a/b", "0.0.0.0/0"]),
)
values = st.recursive(
    scalars, lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner, max_size=3),
    max_leaves=6,
)


def _paths(data: Any, prefix: tuple = ()) -> list[tuple]:
    out = [prefix]
    if isinstance(data, dict):
        for key, value in data.items():
            out += _paths(value, prefix + (key,))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            out += _paths(value, prefix + (i,))
    return out


PATHS = _paths(BASE)[1:]


@st.composite
def edited(draw: st.DrawFn) -> dict:
    data = copy.deepcopy(BASE)
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(PATHS))
        parent: Any = data
        try:
            for part in path[:-1]:
                parent = parent[part]
            action = draw(st.sampled_from(["replace", "delete", "add"]))
            if action == "replace":
                parent[path[-1]] = draw(values)
            elif action == "delete" and isinstance(parent, dict):
                parent.pop(path[-1], None)
            elif isinstance(parent, dict):
                parent[draw(st.text(max_size=8))] = draw(values)
        except (KeyError, IndexError, TypeError):
            continue
    return data


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(edited())
def test_random_edits_validate_or_give_error_lines(data: dict) -> None:
    text = yaml.safe_dump(data, sort_keys=False)
    try:
        manifest = parse_manifest(text, source="m.yaml")
    except ManifestError as err:
        assert err.problems
        for line in err.problems:
            assert line.startswith("m.yaml:") and "\n" not in line
            assert line.split(":")[1].isdigit()
    else:
        assert isinstance(manifest, Manifest)
