"""Terraform plan JSON without a cloud: a provider of its own here, and a plan document by hand."""

from __future__ import annotations

from typing import Any

import pytest

from fogiac.errors import PlanError
from fogiac.pulumi_engine import terraform

SHELF = terraform.Provider(
    name="shelf", source="registry.terraform.io/example/shelf", types_home="tests.SHELF.types",
    types={"shelf:index:Box": "shelf_box", "shelf:index:Rule": "shelf_rule"},
    renamed={("shelf_box", "lids"): "lid"}, maps=frozenset({"labels"}),
    config=lambda doc: {"region": {"constant_value": doc["region"]}},
    by_design=lambda doc: [{"check": "CKV_SHELF_1", "reason": "boxes are open on purpose"}])


def _doc(*rows: dict[str, Any]) -> dict[str, Any]:
    return {"stack": "s-dev", "plan_digest": "d", "region": "moon-1", "resources": list(rows)}


def test_types_attributes_blocks_maps_and_references() -> None:
    doc = _doc({"type": "shelf:index:Box", "name": "s-dev-box", "inputs": {
                   "sizeGb": 3, "labels": {"fogiac:stack": "s-dev"}, "lids": [{"colourName": "red"}]}},
               {"type": "shelf:index:Rule", "name": "s-dev.rule", "inputs": {"boxId": "<s-dev-box.id>"}})
    out = terraform.export(doc, SHELF)
    box, rule = out["planned_values"]["root_module"]["resources"]
    assert box["address"] == "shelf_box.s-dev-box" and box["provider_name"] == SHELF.source
    assert box["values"] == {"size_gb": 3, "labels": {"fogiac:stack": "s-dev"}, "lid": [{"colour_name": "red"}]}
    assert rule["address"] == "shelf_rule.s-dev_rule" and rule["values"] == {}
    change = out["resource_changes"][1]["change"]
    assert change["actions"] == ["create"] and change["after_unknown"] == {"box_id": True}
    configured = out["configuration"]["root_module"]["resources"][1]
    assert configured["expressions"] == {"box_id": {"references": ["shelf_box.s-dev-box.id", "shelf_box.s-dev-box"]}}
    assert configured["provider_config_key"] == "shelf"
    assert out["configuration"]["provider_config"]["shelf"]["expressions"] == {"region": {"constant_value": "moon-1"}}
    assert out["fogiac"]["by_design"] == [{"check": "CKV_SHELF_1", "reason": "boxes are open on purpose"}]


def test_a_replaced_resource_has_its_inputs_before() -> None:
    doc = _doc({"type": "shelf:index:Box", "name": "b", "action": "replace", "inputs": {"sizeGb": 4},
                "before": {"sizeGb": 3}})
    (change,) = terraform.export(doc, SHELF)["resource_changes"]
    assert change["change"]["actions"] == ["delete", "create"]
    assert change["change"]["before"] == {"size_gb": 3} and change["change"]["after"] == {"size_gb": 4}


def test_an_unknown_type_names_where_to_add_it() -> None:
    with pytest.raises(PlanError, match=r"^no Terraform type known for 'shelf:index:Cup'; "
                                        r"add it to tests\.SHELF\.types$"):
        terraform.export(_doc({"type": "shelf:index:Cup", "name": "c", "inputs": {}}), SHELF)
