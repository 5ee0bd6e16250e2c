"""Rebuilding the catalogue: EC2 facts from LocalStack, the Price List under botocore's Stubber, a SkyPilot CSV.

LocalStack serves DescribeInstanceTypes, DescribeInstanceTypeOfferings and DescribeSpotPriceHistory
(moto's recorded AWS answers); it has no Price List API, so ``pricing`` is a real botocore client
with a Stubber in front of it. What the refresh writes is read back with ``catalogue.read``, the
same loader ``load(path)`` uses.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from fogiac.targets.aws import catalogue
from fogiac.targets.aws.refresh import CatalogueUnavailable, from_aws, from_skypilot_csv, parse_price_item

boto3 = pytest.importorskip("boto3")
stub = pytest.importorskip("botocore.stub")


def _price_item(itype: str, region: str, usd: str) -> str:
    return json.dumps({
        "product": {"productFamily": "Compute Instance",
                    "attributes": {"instanceType": itype, "regionCode": region, "operatingSystem": "Linux",
                                   "tenancy": "Shared"}},
        "terms": {"OnDemand": {"SKU.TERM": {"priceDimensions": {"SKU.TERM.DIM": {
            "unit": "Hrs", "pricePerUnit": {"USD": usd}}}}}},
    })


def _pricing(items: list[str] | None = None, *, error: str | None = None) -> tuple[Any, Any]:
    client = boto3.session.Session(region_name="us-east-1", aws_access_key_id="test",
                                   aws_secret_access_key="test").client("pricing")
    stubber = stub.Stubber(client)
    expected = {"ServiceCode": "AmazonEC2", "Filters": stub.ANY}
    if error:
        stubber.add_client_error("get_products", service_error_code=error, service_message="not for you",
                                 expected_params=expected)
    else:
        stubber.add_response("get_products", {"PriceList": items or [], "FormatVersion": "aws_v1"}, expected)
    stubber.activate()
    return client, stubber


def test_refresh_from_localstack_and_the_price_list_writes_a_catalogue_load_reads(
        aws_env: str, tmp_path: Path) -> None:
    from fogiac.targets.aws.api import client

    pricing, stubber = _pricing([_price_item("g6.xlarge", "eu-central-1", "0.9776000000"),
                                 _price_item("c7g.4xlarge", "eu-central-1", "0.6528000000"),
                                 _price_item("g6.xlarge", "ap-south-1", "1.0")])  # a region not asked for
    built = from_aws(regions=["eu-central-1"], ec2_for=lambda r: client("ec2", region=r), pricing=pricing,
                     today="2026-11-26")
    stubber.assert_no_pending_responses()
    path = built.write(tmp_path / "catalogue.json.gz")

    cat = catalogue.read(path)
    assert cat.regions == ("eu-central-1",)
    assert cat.offered("g6.xlarge", "eu-central-1") and not cat.offered("g6.xlarge", "ap-south-1")
    spec = cat.get("g6.xlarge")
    assert spec is not None and (spec.gpus, spec.gpu_model, spec.arch) == (1, "L4", "x86_64")
    graviton = cat.get("c7g.4xlarge")
    assert graviton is not None and graviton.arch == "arm64"
    price = cat.price("g6.xlarge", "eu-central-1")
    assert price is not None and price.usd_per_hour == 0.9776
    assert price.source.date == "2026-11-26" and "Price List" in price.source.name
    assert names_priced(cat, "eu-central-1") == ["c7g.4xlarge", "g6.xlarge"]
    assert cat.spot("g6.xlarge", "eu-central-1") is not None  # LocalStack serves spot price history
    assert catalogue.names(cat.search(region="eu-central-1", gpu="L4")) == ["g6.xlarge"]


def names_priced(cat: catalogue.Catalogue, region: str) -> list[str]:
    return sorted(n for n in cat.types if cat.price(n, region) is not None)


def test_a_price_list_refusal_is_one_line(aws_env: str) -> None:
    from fogiac.targets.aws.api import client

    pricing, _ = _pricing(error="AccessDeniedException")
    with pytest.raises(CatalogueUnavailable, match=r"^catalogue refresh: Price List API GetProducts in us-east-1 "
                       r"refused \(AccessDeniedException: not for you\); the shipped catalogue stays in use$"):
        from_aws(regions=["eu-central-1"], ec2_for=lambda r: client("ec2", region=r), pricing=pricing, spot=False)


def test_an_ec2_refusal_names_the_api_and_the_region() -> None:
    ec2 = boto3.session.Session(region_name="eu-west-1", aws_access_key_id="test",
                                aws_secret_access_key="test").client("ec2")
    stubber = stub.Stubber(ec2)
    stubber.add_client_error("describe_instance_types", service_error_code="UnauthorizedOperation",
                             service_message="You are not authorized")
    stubber.activate()
    with pytest.raises(CatalogueUnavailable, match=r"^catalogue refresh: DescribeInstanceTypes in eu-west-1 "
                       r"refused \(UnauthorizedOperation: You are not authorized\)"):
        from_aws(regions=["eu-west-1"], ec2_for=lambda r: ec2, pricing=None)


def test_an_unreachable_endpoint_is_one_line() -> None:
    ec2 = boto3.session.Session(region_name="eu-west-1", aws_access_key_id="test",
                                aws_secret_access_key="test").client(
        "ec2", endpoint_url="http://127.0.0.1:9", config=__import__("botocore.config").config.Config(
            connect_timeout=1, retries={"max_attempts": 1}))
    with pytest.raises(CatalogueUnavailable, match=r"^catalogue refresh: DescribeInstanceTypes in eu-west-1 "
                       r"unavailable \(Could not connect"):
        from_aws(regions=["eu-west-1"], ec2_for=lambda r: ec2, pricing=None)


L4 = "\"{'Gpus': [{'Name': 'L4', 'Manufacturer': 'NVIDIA', 'Count': 1, 'MemoryInfo': {'SizeInMiB': 22888}}], " \
     "'TotalGpuMemoryInMiB': 22888}\""
CSV = "\n".join([
    "InstanceType,AcceleratorName,AcceleratorCount,vCPUs,MemoryGiB,GpuInfo,Price,SpotPrice,Region,AvailabilityZone,Arch",
    f"g6.xlarge,L4,1.0,4.0,16.0,{L4},1.00637,0.30,eu-central-1,euc1-az2,x86_64",
    f"g6.xlarge,L4,1.0,4.0,16.0,{L4},1.00637,0.40,eu-central-1,euc1-az3,x86_64",
    f"g6.xlarge,L4,1.0,4.0,16.0,{L4},0.8048,0.35,us-east-1,use1-az1,x86_64",
    "c7g.4xlarge,,,16.0,32.0,,0.6528,0.25,eu-west-1,euw1-az1,arm64",
    "t2.micro,,,1.0,1.0,,0.0138,,us-west-1,usw1-az1,x86_64",
]) + "\n"


def test_a_skypilot_csv_builds_the_same_format(tmp_path: Path) -> None:
    (tmp_path / "vms.csv").write_text(CSV)
    path = from_skypilot_csv(tmp_path / "vms.csv", commit="abc123", date="2026-11-20").write(tmp_path / "c.json.gz")
    cat = catalogue.read(path)
    assert set(cat.regions) == {"eu-central-1", "us-east-1", "eu-west-1", "us-west-1"}
    g6 = cat.get("g6.xlarge")
    assert g6 is not None and (g6.gpus, g6.gpu_model, g6.gpu_memory_gib, g6.accelerator_kind) == (1, "L4", 22.4, "gpu")
    price, spot = cat.price("g6.xlarge", "eu-central-1"), cat.spot("g6.xlarge", "eu-central-1")
    assert price is not None and price.usd_per_hour == 1.00637 and "abc123" in price.source.detail
    assert spot is not None and spot.usd_per_hour == 0.35 and spot.source.estimate  # median of the zones
    assert cat.regions_offering("g6.xlarge") == ("eu-central-1", "us-east-1")
    c7g = cat.get("c7g.4xlarge")
    assert c7g is not None and c7g.arch == "arm64" and cat.offered("c7g.4xlarge", "eu-west-1")
    assert cat.spot("t2.micro", "us-west-1") is None and cat.price("t2.micro", "us-west-1") is not None
    assert cat.provenance["input"]["commit"] == "abc123"


def test_price_list_items_that_are_not_hourly_prices_are_skipped() -> None:
    assert parse_price_item(_price_item("m5.large", "us-east-1", "0.096")) == ("m5.large", "us-east-1", 0.096)
    assert parse_price_item(_price_item("m5.large", "us-east-1", "0.0000000000")) is None
    assert parse_price_item({"product": {"attributes": {}}, "terms": {}}) is None
