"""The shipped instance catalogue: every region, its facts, its search and its suggestions (offline)."""

from __future__ import annotations

import time

import pytest

from fogiac.targets.aws import catalogue
from fogiac.targets.aws.catalogue import load, names, not_offered, suggest_region, suggest_type


@pytest.fixture(scope="module")
def cat() -> catalogue.Catalogue:
    return load()


def test_covers_every_commercial_region_and_the_families_users_name(cat: catalogue.Catalogue) -> None:
    assert len(cat.regions) >= 30
    for region in ("us-east-1", "us-west-1", "eu-central-1", "eu-west-1", "ap-northeast-1", "sa-east-1"):
        assert region in cat.regions
    for name in ("t2.micro", "t2.medium", "m4.large", "p3.2xlarge", "c7i.8xlarge", "g6e.xlarge", "p5.48xlarge"):
        assert name in cat, name
    assert len(cat.types) > 1000


def test_g6_xlarge_in_eu_central_1_is_offered_and_priced_with_a_dated_source(cat: catalogue.Catalogue) -> None:
    spec = cat.get("g6.xlarge")
    assert spec is not None and (spec.gpus, spec.gpu_model, spec.vcpus, spec.arch) == (1, "L4", 4, "x86_64")
    assert spec.gpu_memory_gib == pytest.approx(22.4, abs=0.1)
    assert cat.offered("g6.xlarge", "eu-central-1")
    price = cat.price("g6.xlarge", "eu-central-1")
    assert price is not None and 0.8 < price.usd_per_hour < 1.2
    assert price.source.date and price.source.name
    spot = cat.spot("g6.xlarge", "eu-central-1")
    assert spot is not None and spot.usd_per_hour < price.usd_per_hour and spot.source.estimate


def test_us_east_1_on_demand_is_the_price_list_not_an_estimate(cat: catalogue.Catalogue) -> None:
    price = cat.price("g6.xlarge", "us-east-1")
    assert price is not None and price.usd_per_hour == pytest.approx(0.8048)
    assert not price.source.estimate and "Price List" in price.source.name


def test_graviton_is_arm64_and_offered_in_eu_west_1(cat: catalogue.Catalogue) -> None:
    spec = cat.get("c7g.4xlarge")
    assert spec is not None and (spec.arch, spec.vcpus, spec.memory_gib) == ("arm64", 16, 32.0)
    assert cat.offered("c7g.4xlarge", "eu-west-1") and cat.price("c7g.4xlarge", "eu-west-1") is not None


def test_t2_micro_is_offered_and_priced_in_us_west_1(cat: catalogue.Catalogue) -> None:
    assert cat.offered("t2.micro", "us-west-1")
    price = cat.price("t2.micro", "us-west-1")
    assert price is not None and 0.01 < price.usd_per_hour < 0.02


def test_an_l4_with_4_vcpus_in_us_east_1_is_a_g6_xlarge(cat: catalogue.Catalogue) -> None:
    found = cat.search(region="us-east-1", gpu="L4", vcpus=">=4")
    assert names(found)[:2] == ["g6.xlarge", "g6.2xlarge"]
    prices = [o.rank_price() for o in found]
    assert prices == sorted(prices)


def test_an_a10g_with_16_vcpus_in_us_west_2_is_a_g5_4xlarge(cat: catalogue.Catalogue) -> None:
    assert names(cat.search(region="us-west-2", gpu="a10g", vcpus=">=16"))[0] == "g5.4xlarge"


def test_search_filters_by_arch_and_gpu_memory(cat: catalogue.Catalogue) -> None:
    arm = cat.search(region="eu-west-1", arch="arm64", vcpus=">=8")
    assert arm and all(o.type.arch == "arm64" and o.type.vcpus >= 8 for o in arm)
    big = cat.search(region="us-east-1", gpu=True, gpu_memory_gib=">=40")
    assert big and all(o.type.gpu_memory_gib >= 40 for o in big)
    assert cat.search(region="us-east-1", gpu="no-such-gpu") == []
    with pytest.raises(ValueError, match=r"'lots' is not a bound"):
        cat.search(region="us-east-1", vcpus="lots")


def test_regions_offering_p4d_and_the_refusal_that_names_them(cat: catalogue.Catalogue) -> None:
    where = cat.regions_offering("p4d.24xlarge")
    assert "us-east-1" in where and "us-west-2" in where and "us-west-1" not in where
    assert not_offered(cat, "p4d.24xlarge", "us-west-1") == (
        f"'p4d.24xlarge' is not offered in us-west-1; regions that offer it: {', '.join(where)}")


def test_suggestions_come_from_the_catalogues_facts(cat: catalogue.Catalogue) -> None:
    assert suggest_type(cat, "g6.xlarg")[0] == "g6.xlarge"  # the size misspelt: same family
    assert suggest_type(cat, "t2.mcro")[0] == "t2.micro"
    assert set(suggest_type(cat, "c7gg.4xlarge")) == {"c7g.4xlarge", "c7gd.4xlarge", "c7gn.4xlarge"}
    # a real type the region lacks: the nearest hardware the region has, not the nearest spelling
    nearest = [cat.get(n) for n in suggest_type(cat, "c7g.4xlarge", region="us-west-1")]
    assert all(s is not None and s.arch == "arm64" and s.vcpus == 16 for s in nearest)
    # a region that lacks the type: regions that offer it, nearest first
    assert suggest_region(cat, "eu-wset-1", machine="p4d.24xlarge")[0] == "eu-west-1"
    assert set(suggest_region(cat, "us-west-1", machine="p4d.24xlarge")) <= set(cat.regions_offering("p4d.24xlarge"))


def test_client_vpn_prices_are_kept(cat: catalogue.Catalogue) -> None:
    assert cat.client_vpn_usd_per_hour["association"] == 0.1
    assert cat.client_vpn_usd_per_hour["connection"] == 0.05


def test_provenance_names_every_input_with_commit_and_licence(cat: catalogue.Catalogue) -> None:
    for item in cat.provenance["inputs"]:
        assert item["license"]
        assert item.get("commit") or item.get("package")


def test_loading_and_one_lookup_stay_cheap() -> None:
    load.cache_clear()
    start = time.perf_counter()
    cat = load()
    assert cat.price("g6.xlarge", "eu-central-1") is not None
    assert time.perf_counter() - start < 0.2  # validate's whole budget is 0.3 s


def test_a_region_without_a_price_source_is_offered_but_unpriced(cat: catalogue.Catalogue) -> None:
    # sa-east-1 has no measured price ratio in the shipped file: known, offered, cost unknown until a refresh
    assert cat.offered("g4dn.xlarge", "sa-east-1")
    assert cat.price("g4dn.xlarge", "sa-east-1") is None and cat.spot("g4dn.xlarge", "sa-east-1") is None
    assert cat.search(region="sa-east-1", gpu="T4") == []
    assert "g4dn.xlarge" in names(cat.search(region="sa-east-1", gpu="T4", priced_only=False))


def test_carrying_the_catalogue_over_reads_each_types_zones_a_bounded_number_of_times(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """`catalog update --region R` carries every other region over (Builder.keep), asking zones_offering for each
    (type, region); each ask gathered the region's zones over every type afresh, so one update read zones
    ~60 million times and took half a minute. Counted in reads, not seconds: each region is gathered once."""
    from fogiac.targets.aws.refresh import Builder

    load.cache_clear()
    cat = load()
    reads = 0
    zones_of = catalogue.Catalogue._zones_of

    def counted(self: catalogue.Catalogue, name: str) -> dict[str, tuple[str, ...]]:
        nonlocal reads
        reads += 1
        return zones_of(self, name)

    monkeypatch.setattr(catalogue.Catalogue, "_zones_of", counted)
    built = Builder()
    kept = built.keep(cat, refreshed=["sa-east-1"])
    load.cache_clear()
    assert "sa-east-1" not in kept and "us-east-1" in kept
    assert built.zones  # zones were carried over
    # one read per (type, region) asked, plus one gathering of every type per region
    assert reads <= len(cat.types) * len(cat.regions) * 2, reads
