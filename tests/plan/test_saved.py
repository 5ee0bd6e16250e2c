"""Saved plans are honoured only for the manifest bytes and fogiac version that made them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fogiac.plan.compile import compile_plan
from fogiac.targets import get as target
from fogiac.errors import FogiacError, PlanError
from fogiac.manifest.schema import load_manifest
from fogiac.plan.document import plan_document
from fogiac.targets import get as get_target
from fogiac.plan.saved import check_saved_plan

MINIMAL = Path(__file__).parents[2] / "examples" / "minimal.yaml"


@pytest.fixture
def saved(tmp_path: Path) -> tuple[Path, Path]:
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_bytes(MINIMAL.read_bytes())
    plan = compile_plan(load_manifest(manifest))
    doc = plan_document(plan, get_target(plan.target).declare(plan), manifest=manifest)
    out = tmp_path / "plan.json"
    out.write_text(json.dumps(doc))
    return manifest, out


def test_unchanged_manifest_is_accepted(saved: tuple[Path, Path]) -> None:
    manifest, out = saved
    assert check_saved_plan(out, manifest=manifest, stack="minimal-dev", target="aws")["stack"] == "minimal-dev"


def test_changed_manifest_is_refused(saved: tuple[Path, Path]) -> None:
    manifest, out = saved
    manifest.write_text(manifest.read_text().replace("t3.small", "t3.medium"))
    with pytest.raises(PlanError, match=rf"^saved plan {out} was made from another version of {manifest} "
                                        r"\(sha256 [0-9a-f]{12} there, [0-9a-f]{12} now\); run `fogiac plan --out` again$"):
        check_saved_plan(out, manifest=manifest, stack="minimal-dev", target="aws")


def test_other_fogiac_version_is_refused(saved: tuple[Path, Path]) -> None:
    manifest, out = saved
    doc = json.loads(out.read_text())
    out.write_text(json.dumps({**doc, "fogiac_version": "0.0.1"}))
    with pytest.raises(PlanError, match=r"was made by fogiac 0\.0\.1, this is \d+\.\d+\.\d+; run `fogiac plan --out` again$"):
        check_saved_plan(out, manifest=manifest, stack="minimal-dev", target="aws")


def test_other_environment_is_refused(saved: tuple[Path, Path]) -> None:
    manifest, out = saved
    with pytest.raises(PlanError, match=r"is for stack minimal-dev on aws, not minimal-prod on aws; pass the same"):
        check_saved_plan(out, manifest=manifest, stack="minimal-prod", target="aws")


def test_not_a_plan_is_refused(tmp_path: Path) -> None:
    (tmp_path / "p.json").write_text("{}")
    with pytest.raises(PlanError, match=r"is not a fogiac plan document \(format_version 2\)$"):
        check_saved_plan(tmp_path / "p.json", manifest=MINIMAL, stack="minimal-dev", target="aws")
    with pytest.raises(PlanError, match=r"does not exist$"):
        check_saved_plan(tmp_path / "none.json", manifest=MINIMAL, stack="minimal-dev", target="aws")


def test_unknown_targets_name_the_registered_ones() -> None:
    with pytest.raises(FogiacError, match=r"^unknown target 'gcp'; valid: aws, hosts, local$"):
        target("gcp")
