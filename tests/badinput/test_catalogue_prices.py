"""Issue 35 item 10: a catalogue's prices are checked where they are read. NaN, negative and infinite
prices (in a catalogue file, a Price List answer, a spot history, a SkyPilot CSV) are refused in one
line naming the entry; before, a NaN catalogue chose a 192-vCPU machine for ``vcpus: '>=2'`` and a
negative total passed the cost guard."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.targets.aws import catalogue
from fogiac.targets.aws.catalogue import BadPrice
from fogiac.targets.aws.refresh import Builder, from_skypilot_csv, parse_price_item

BAD = ["nan", "-0.5", "inf", "-inf", "1e999"]

MANIFEST = """\
name: cheap
cloud:
  provider: aws
  region: us-west-2
nodes:
  - name: talker
    machine: {vcpus: '>=2'}
    image: ros:noetic-ros-core
"""


def _catalogue(path: Path, small: str, big: str = "0.5") -> Path:
    """Two types in us-west-2: a small one priced ``small`` and a 192-vCPU one priced ``big``."""
    b = Builder(provenance={"built": "test"})
    src = b.source(catalogue.Source("test", "2026-11-28", "hostile"))
    b.hardware["m5.large"] = [2, 8.0, "x86_64", 0, None, 0.0, None, src]
    b.hardware["m7i.48xlarge"] = [192, 768.0, "x86_64", 0, None, 0.0, None, src]
    for name in b.hardware:
        b.offer(name, "us-west-2")
    doc = b.document()
    doc["types"]["m5.large"][9] = f"0,{small},{src},,"
    doc["types"]["m7i.48xlarge"][9] = f"0,{big},{src},,"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize("bad", BAD)
def test_a_catalogue_price_that_is_not_a_price_is_refused_naming_the_entry(bad: str, tmp_path: Path) -> None:
    cat = catalogue.read(_catalogue(tmp_path / "cat.json", bad))
    with pytest.raises(BadPrice, match=rf"^{tmp_path / 'cat.json'}: m5.large in us-west-2 \(on-demand\): "
                                       rf"price '{bad}' is not a finite number of dollars at least 0$"):
        cat.search(region="us-west-2", vcpus=">=2")


@pytest.mark.parametrize("bad", ["nan", "-1"])
def test_plan_with_a_hostile_user_catalogue_is_one_line(bad: str, tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    state = tmp_path / "state"
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(state))
    written = _catalogue(state / "catalogue" / "aws.json.gz", bad)
    (tmp_path / "fogiac.yaml").write_text(MANIFEST)
    for argv in (["plan", str(tmp_path / "fogiac.yaml")], ["catalog", "--region", "us-west-2"]):
        result = CliRunner().invoke(app, argv)
        assert result.exit_code == 1, result.output
        assert result.output.strip().splitlines() == [
            f"error: {written}: m5.large in us-west-2 (on-demand): price '{bad}' is not a finite number of "
            "dollars at least 0"], result.output


def test_a_hostile_client_vpn_price_is_refused(tmp_path: Path) -> None:
    path = _catalogue(tmp_path / "cat.json", "0.1")
    doc = json.loads(path.read_text())
    doc["client_vpn_usd_per_hour"]["association"] = -0.1
    path.write_text(json.dumps(doc))
    with pytest.raises(BadPrice, match=r"client_vpn_usd_per_hour association: price -0.1 is not a finite"):
        catalogue.read(path)


def _item(usd: str) -> str:
    return json.dumps({"product": {"attributes": {"instanceType": "m5.large", "regionCode": "eu-west-1"}},
                       "terms": {"OnDemand": {"T": {"priceDimensions": {"D": {"pricePerUnit": {"USD": usd}}}}}}})


@pytest.mark.parametrize("bad", ["NaN", "-0.096", "Infinity", "lots"])
def test_a_price_list_answer_that_is_not_a_price_is_refused(bad: str) -> None:
    with pytest.raises(BadPrice, match=r"^Price List entry m5.large in eu-west-1: price '.*' is not a"):
        parse_price_item(_item(bad))
    assert parse_price_item(_item("0.0000000000")) is None  # a zero dimension is still skipped, as before


@pytest.mark.parametrize("column", ["Price", "SpotPrice"])
def test_a_skypilot_csv_price_that_is_not_a_price_is_refused_naming_its_line(column: str, tmp_path: Path) -> None:
    path = tmp_path / "vms.csv"
    prices = {"Price": "0.096", "SpotPrice": "0.04", column: "nan"}
    path.write_text("InstanceType,AcceleratorName,AcceleratorCount,vCPUs,MemoryGiB,GpuInfo,Price,SpotPrice,Region,"
                    "AvailabilityZone,Arch\n"
                    f"m5.large,,,2,8,,{prices['Price']},{prices['SpotPrice']},eu-west-1,eu-west-1a,x86_64\n")
    with pytest.raises(BadPrice, match=rf"^{path} line 2: m5.large in eu-west-1 \({column}\): price 'nan' is not"):
        from_skypilot_csv(path, commit="c", date="d")


def test_a_spot_history_price_that_is_not_a_price_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    """DescribeSpotPriceHistory's answer (AWS's shape, through botocore's Stubber in front of a real client)."""
    monkeypatch.setenv("AWS_ACCESS_KEY_ID", "test")
    monkeypatch.setenv("AWS_SECRET_ACCESS_KEY", "test")
    stub = pytest.importorskip("botocore.stub")
    from fogiac.targets.aws.api import client

    ec2 = client("ec2", region="eu-west-1")
    stubber = stub.Stubber(ec2)
    stubber.add_response("describe_instance_types", {"InstanceTypes": []})
    stubber.add_response("describe_instance_type_offerings", {"InstanceTypeOfferings": []})
    stubber.add_response("describe_spot_price_history", {"SpotPriceHistory": [
        {"InstanceType": "m5.large", "AvailabilityZone": "eu-west-1a", "SpotPrice": "-Infinity",
         "ProductDescription": "Linux/UNIX"}]})
    from fogiac.targets.aws.refresh import from_aws

    with stubber, pytest.raises(BadPrice, match=r"^DescribeSpotPriceHistory in eu-west-1: m5.large in eu-west-1a: "
                                                r"price '-Infinity' is not a finite number of dollars at least 0$"):
        from_aws(regions=["eu-west-1"], ec2_for=lambda r: ec2, pricing=None)
