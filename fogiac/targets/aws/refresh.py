"""Rebuild the instance catalogue: from AWS's own APIs, from a SkyPilot CSV, or from dated snapshots.

Three ways in, one writer (:class:`Builder`), one format (read by :mod:`.catalogue`):

* :func:`from_aws`, with the user's credentials (``fogiac catalog update``): the Price List API
  (``pricing`` in us-east-1, ``get_products`` for AmazonEC2, Linux, shared tenancy, no
  pre-installed software, capacity status Used) for on-demand prices; per region
  ``DescribeInstanceTypes`` (hardware, architecture, GPUs), ``DescribeInstanceTypeOfferings``
  (availability) and ``DescribeSpotPriceHistory`` (the median of the latest Linux/UNIX spot price
  across the region's zones). An API that refuses or cannot be reached ends it with one
  :class:`CatalogueUnavailable` line naming the API and the region.
* :func:`from_skypilot_csv`, a ``catalogs/v8/aws/vms.csv`` from ``skypilot-org/skypilot-catalog``
  (which SkyPilot's fetchers write from the same APIs; the repository states no licence, SkyPilot
  itself is Apache-2.0; prices and hardware counts are facts), e.g.::

      python -m fogiac.targets.aws.refresh --from-csv vms.csv --source-commit <sha> --source-date <date> \\
          --out fogiac/targets/aws/data/catalogue.json.gz

* :func:`from_snapshots`, which is how the shipped file was made (2026-11-26), because a whole
  vms.csv could not be brought onto the build machine that day::

      python -m fogiac.targets.aws.refresh --from-snapshots \\
          --moto <moto-ext 5.1.54 site-packages>/moto/ec2/resources \\
          --older-moto <moto 5.0.28 wheel, unpacked>/moto/ec2/resources \\
          --karpenter-prices pkg/providers/pricing/zz_generated.pricing_aws.go \\
          --spot-advisor internal/spot/data/spot-advisor-data.json \\
          --out fogiac/targets/aws/data/catalogue.json.gz

  Hardware and per-region availability come from moto-ext 5.1.54's ``instance_types.json.gz``
  and ``instance_type_offerings/region/*.json.gz`` (Apache-2.0; verbatim DescribeInstanceTypes
  and DescribeInstanceTypeOfferings answers); moto 5.0.28 (2025-02-02) adds the previous generations
  AWS stopped listing since (p2, p3, g4ad, f1, dl1). us-east-1 on-demand prices come from Karpenter's
  ``zz_generated.pricing_aws.go`` (aws/karpenter-provider-aws, Apache-2.0, generated from the
  Price List API 2026-07-20). Other regions are *estimates*: the us-east-1 price times the
  region's median price ratio, measured on the SkyPilot rows in :data:`_REGION_SAMPLES` (seven
  types); regions with no measured ratio (sa-east-1, ap-south-2, ap-southeast-5, ca-west-1,
  eu-central-2, il-central-1: SkyPilot's catalogue has no rows there) stay unpriced. Spot is an
  estimate too: on-demand less the AWS Spot Instance Advisor's saving (snapshot in
  alexei-led/spotinfo, 2025-06-28). Each of these is a source in the file, flagged ``estimate``
  where it is one; a refresh replaces them with AWS's own.
"""

from __future__ import annotations

import argparse
import ast
import csv
import datetime as _dt
import gzip
import json
import re
import statistics
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from fogiac.errors import CloudError
from fogiac.extras import need
from fogiac.targets.aws.catalogue import FORMAT, Catalogue, Source, checked_price

CLIENT_VPN_USD_PER_HOUR = {"association": 0.1, "connection": 0.05}  # us-east-1 list price, as before
_CLIENT_VPN_SOURCE = "AWS Client VPN pricing page (aws.amazon.com/vpn/pricing), us-east-1, 2025-06"
PRICING_REGION = "us-east-1"  # the Price List API answers here (and in ap-south-1, eu-central-1)
_PRICE_FILTERS = [
    {"Type": "TERM_MATCH", "Field": k, "Value": v} for k, v in (
        ("operatingSystem", "Linux"), ("tenancy", "Shared"), ("preInstalledSw", "NA"),
        ("capacitystatus", "Used"), ("licenseModel", "No License required"))
]


_SKYPILOT_LICENSE = "none stated (no LICENSE file in skypilot-org/skypilot-catalog, checked 2026-11-26); facts"


class CatalogueUnavailable(CloudError):
    """An AWS API the refresh needs refused or could not be reached."""


@dataclass
class Builder:
    """Facts gathered from any source, then written in the catalogue format."""

    provenance: dict[str, Any] = field(default_factory=dict)
    sources: list[Source] = field(default_factory=list)
    hardware: dict[str, list[Any]] = field(default_factory=dict)  # type -> [vcpus, mem, arch, n, model, mem, kind, src]
    offered: dict[str, set[str]] = field(default_factory=dict)  # type -> regions
    on_demand: dict[tuple[str, str], tuple[float, int]] = field(default_factory=dict)
    spot: dict[tuple[str, str], tuple[float, int]] = field(default_factory=dict)
    zones: dict[str, dict[str, set[str]]] = field(default_factory=dict)  # type -> region -> zones offering it

    def source(self, source: Source) -> int:
        if source not in self.sources:
            self.sources.append(source)
        return self.sources.index(source)

    def add_hardware(self, record: Mapping[str, Any], src: int) -> None:
        """One DescribeInstanceTypes record (as the API returns it)."""
        self.hardware[record["InstanceType"]] = hardware_row(record) + [src]

    def offer(self, itype: str, region: str) -> None:
        self.offered.setdefault(itype, set()).add(region)

    def zone(self, itype: str, zone: str) -> None:
        """One availability-zone offering (a DescribeInstanceTypeOfferings answer by zone)."""
        self.zones.setdefault(itype, {}).setdefault(zone[:-1], set()).add(zone)

    def keep(self, cat: Catalogue, *, refreshed: Iterable[str]) -> list[str]:
        """Carry over from ``cat`` what this build did not read: every other region's offers, prices and
        zones (each with its own source and date), the hardware of types it did not see, and zones it did
        not ask for. A refresh of one region fills that region; it must not drop the others. Returns the
        regions kept."""
        fresh = set(refreshed)
        sources: dict[Source, int] = {}

        def source(found: Source) -> int:
            if found not in sources:
                sources[found] = self.source(found)
            return sources[found]

        kept = [r for r in cat.regions if r not in fresh]
        self.provenance["kept"] = {"from": cat.path, "regions": kept, "provenance": dict(cat.provenance)}
        for name in cat.types:
            spec = cat.get(name)
            if spec is None:
                continue
            if name not in self.hardware:
                self.hardware[name] = [spec.vcpus, spec.memory_gib, spec.arch, spec.gpus, spec.gpu_model,
                                       spec.gpu_memory_gib, spec.accelerator_kind, source(spec.hardware_source)]
            for region in cat.regions_offering(name):
                if region not in fresh:
                    self.offer(name, region)
            for region in kept:
                for column, price in ((self.on_demand, cat.price(name, region)), (self.spot, cat.spot(name, region))):
                    if price is not None:
                        column[(name, region)] = (price.usd_per_hour, source(price.source))
            for region in cat.regions:
                zones = cat.zones_offering(name, region)
                if zones and region not in self.zones.get(name, {}):
                    self.zones.setdefault(name, {})[region] = set(zones)
        return kept

    def document(self) -> dict[str, Any]:
        regions = sorted({r for rs in self.offered.values() for r in rs}
                         | {r for _, r in self.on_demand} | {r for _, r in self.spot})
        index = {r: i for i, r in enumerate(regions)}
        types: dict[str, list[Any]] = {}
        for name in sorted(self.hardware):
            mask = sum(1 << index[r] for r in self.offered.get(name, ()))
            points = []
            for region in regions:
                od, sp = self.on_demand.get((name, region)), self.spot.get((name, region))
                if od or sp:
                    points.append(",".join(_cell(v) for v in (index[region], *(od or ("", "")), *(sp or ("", "")))))
            types[name] = [*self.hardware[name], mask, ";".join(points)]
        return {"format": FORMAT, "provenance": self.provenance, "sources": [asdict(s) for s in self.sources],
                "regions": regions, "client_vpn_usd_per_hour": {**CLIENT_VPN_USD_PER_HOUR,
                                                                "source": _CLIENT_VPN_SOURCE},
                "types": types, **({"zones": encode_zones(self.zones, index)} if self.zones else {})}

    def write(self, path: str | Path) -> Path:
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        text = json.dumps(self.document(), separators=(",", ":"), sort_keys=False)
        out.write_bytes(gzip.compress(text.encode(), compresslevel=9, mtime=0))
        return out


def encode_zones(zones: Mapping[str, Mapping[str, set[str]]], index: Mapping[str, int]) -> dict[str, str]:
    """type -> ``"region index:zone letters;..."``: which zones of each region offer the type."""
    return {name: ";".join(f"{index[region]}:{''.join(sorted(z[-1] for z in found))}"
                           for region, found in sorted(by_region.items(), key=lambda kv: index[kv[0]])
                           if region in index)
            for name, by_region in sorted(zones.items())}


def moto_zones(moto: str | Path) -> dict[str, dict[str, set[str]]]:
    """type -> region -> zones, from moto's ``instance_type_offerings/availability-zone/*.json.gz``."""
    b = Builder()
    for f in sorted((Path(moto) / "instance_type_offerings" / "availability-zone").glob("*.json.gz")):
        for item in json.loads(gzip.decompress(f.read_bytes())):
            b.zone(item["InstanceType"], item["Location"])
    return b.zones


def _cell(value: Any) -> str:
    return "" if value is None else format(value, "g") if isinstance(value, float) else str(value)


def hardware_row(record: Mapping[str, Any]) -> list[Any]:
    """[vcpus, memory GiB, arch, accelerators, model, accelerator memory GiB, kind] of one record."""
    archs = record.get("ProcessorInfo", {}).get("SupportedArchitectures", ["x86_64"])
    arch = "arm64" if "arm64" in archs and "x86_64" not in archs else "x86_64"
    kinds = (("GpuInfo", "Gpus", "TotalGpuMemoryInMiB", "gpu"),
             ("NeuronInfo", "NeuronDevices", "TotalNeuronDeviceMemoryInMiB", "neuron"),
             ("InferenceAcceleratorInfo", "Accelerators", "TotalInferenceMemoryInMiB", "neuron"),
             ("FpgaInfo", "Fpgas", "TotalFpgaMemoryInMiB", "fpga"),
             ("MediaAcceleratorInfo", "Accelerators", "TotalMediaMemoryInMiB", "media"))
    count, model, mem, kind = 0, None, 0.0, None
    for key, items, total, what in kinds:
        info = record.get(key)
        if info and info.get(items):
            first = info[items][0]
            count = sum(int(i.get("Count", 0)) for i in info[items])
            model = first.get("Name")
            mem = round(info.get(total, sum(int(i.get("MemoryInfo", {}).get("SizeInMiB", 0)) * int(i.get("Count", 0))
                                            for i in info[items])) / 1024, 1)
            kind = what
            break
    return [int(record["VCpuInfo"]["DefaultVCpus"]), round(record["MemoryInfo"]["SizeInMiB"] / 1024, 3),
            arch, count, model, mem, kind]


# ---------------------------------------------------------------- from AWS's own APIs


def _ask(api: str, region: str, fn: Any, /, **kwargs: Any) -> Any:
    """Call one AWS API; any refusal or unreachable endpoint becomes one CatalogueUnavailable line."""
    errors = need("botocore.exceptions")
    try:
        return fn(**kwargs)
    except errors.ClientError as err:
        code = err.response.get("Error", {}).get("Code", "")
        message = err.response.get("Error", {}).get("Message", "")
        raise CatalogueUnavailable(f"catalogue refresh: {api} in {region} refused ({code}: {message}); "
                                   "the shipped catalogue stays in use") from None
    except (errors.NoCredentialsError, errors.PartialCredentialsError):
        raise CatalogueUnavailable("catalogue refresh needs AWS credentials: set AWS_PROFILE, or "
                                   "AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY") from None
    except errors.BotoCoreError as err:
        raise CatalogueUnavailable(f"catalogue refresh: {api} in {region} unavailable ({err})") from None


def _pages(client: Any, operation: str, key: str, api: str, region: str, **kwargs: Any) -> list[Any]:
    def every() -> list[Any]:
        return [i for page in client.get_paginator(operation).paginate(**kwargs) for i in page.get(key, [])]

    return list(_ask(api, region, every))


def from_aws(*, regions: Sequence[str], ec2_for: Any, pricing: Any, today: str | None = None,
             spot: bool = True) -> Builder:
    """Facts from the account's view of AWS. ``ec2_for(region)`` returns an EC2 client for that
    region; ``pricing`` is a Price List client (us-east-1). Both are parameters so tests pass
    LocalStack's clients and botocore Stubbers."""
    day = today or _dt.date.today().isoformat()
    b = Builder(provenance={"built": day, "how": "fogiac.targets.aws.refresh.from_aws", "regions": list(regions)})
    hw = b.source(Source("AWS EC2 DescribeInstanceTypes / DescribeInstanceTypeOfferings", day,
                         "the account's own view, per region"))
    od = b.source(Source("AWS Price List API (AmazonEC2, Linux, shared tenancy, on-demand)", day,
                         "pricing.get_products in us-east-1"))
    sp = b.source(Source("AWS EC2 DescribeSpotPriceHistory", day,
                         "median over the region's zones of the latest Linux/UNIX spot price", estimate=True))
    for region in regions:
        ec2 = ec2_for(region)
        for record in _pages(ec2, "describe_instance_types", "InstanceTypes", "DescribeInstanceTypes", region):
            b.hardware.setdefault(record["InstanceType"], hardware_row(record) + [hw])
        for item in _pages(ec2, "describe_instance_type_offerings", "InstanceTypeOfferings",
                           "DescribeInstanceTypeOfferings", region, LocationType="region"):
            b.offer(item["InstanceType"], region)
        if spot:
            latest: dict[tuple[str, str], float] = {}
            history = _pages(ec2, "describe_spot_price_history", "SpotPriceHistory", "DescribeSpotPriceHistory",
                             region, ProductDescriptions=["Linux/UNIX"],
                             StartTime=_dt.datetime.now(_dt.UTC))
            for item in sorted(history, key=lambda i: i.get("Timestamp") or _dt.datetime.min):
                zone = item.get("AvailabilityZone", "")
                latest[(item["InstanceType"], zone)] = checked_price(
                    item.get("SpotPrice"), f"DescribeSpotPriceHistory in {region}: {item['InstanceType']} in {zone}")
            per_type: dict[str, list[float]] = {}
            for (itype, _), value in latest.items():
                per_type.setdefault(itype, []).append(value)
            for itype, values in per_type.items():
                b.spot[(itype, region)] = (round(statistics.median(values), 5), sp)
    wanted = set(regions)
    for product in _pages(pricing, "get_products", "PriceList", "Price List API GetProducts", PRICING_REGION,
                          ServiceCode="AmazonEC2", Filters=_PRICE_FILTERS):
        parsed = parse_price_item(product)
        if parsed and parsed[1] in wanted:
            b.on_demand[(parsed[0], parsed[1])] = (parsed[2], od)
    return b


def parse_price_item(item: str | Mapping[str, Any]) -> tuple[str, str, float] | None:
    """(type, region, USD per hour) from one Price List ``PriceList`` entry, or None if not one."""
    doc = json.loads(item) if isinstance(item, str) else item
    attrs = doc.get("product", {}).get("attributes", {})
    itype, region = attrs.get("instanceType"), attrs.get("regionCode")
    for term in doc.get("terms", {}).get("OnDemand", {}).values():
        for dim in term.get("priceDimensions", {}).values():
            usd = dim.get("pricePerUnit", {}).get("USD")
            if itype and region and usd is not None:
                value = checked_price(usd, f"Price List entry {itype} in {region}")
                if value > 0:  # a zero price is a placeholder dimension, not the type's price
                    return itype, region, round(value, 6)
    return None


# ---------------------------------------------------------------- from a SkyPilot CSV


def from_skypilot_csv(path: str | Path, *, commit: str, date: str) -> Builder:
    """A ``catalogs/v8/aws/vms.csv``: one row per type, region and zone; prices are per region,
    spot the median over the region's zones."""
    b = Builder(provenance={"built": _dt.date.today().isoformat(), "how": "from_skypilot_csv",
                            "input": {"repo": "skypilot-org/skypilot-catalog", "path": "catalogs/v8/aws/vms.csv",
                                      "commit": commit, "date": date, "license": _SKYPILOT_LICENSE}})
    src = b.source(Source("skypilot-org/skypilot-catalog catalogs/v8/aws/vms.csv", date,
                          f"commit {commit}; written by SkyPilot's fetchers from the AWS APIs", _SKYPILOT_LICENSE))
    spot_src = b.source(Source("skypilot-org/skypilot-catalog catalogs/v8/aws/vms.csv SpotPrice", date,
                               f"commit {commit}; median over the region's zones", _SKYPILOT_LICENSE, estimate=True))
    spots: dict[tuple[str, str], list[float]] = {}
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        for row in reader:
            itype, region = row["InstanceType"], row["Region"]
            if itype not in b.hardware:
                b.hardware[itype] = _csv_hardware(row) + [src]
            b.offer(itype, region)
            where = f"{path} line {reader.line_num}: {itype} in {region}"
            if row.get("Price"):
                b.on_demand[(itype, region)] = (round(checked_price(row["Price"], f"{where} (Price)"), 6), src)
            if row.get("SpotPrice"):
                spots.setdefault((itype, region), []).append(checked_price(row["SpotPrice"], f"{where} (SpotPrice)"))
    for key, values in spots.items():
        b.spot[key] = (round(statistics.median(values), 5), spot_src)
    return b


def _csv_hardware(row: Mapping[str, str]) -> list[Any]:
    count = int(float(row.get("AcceleratorCount") or 0))
    model = row.get("AcceleratorName") or None
    mem, kind = 0.0, ("gpu" if model else None)
    if row.get("GpuInfo"):
        info = ast.literal_eval(row["GpuInfo"])
        if isinstance(info, dict):
            total = info.get("TotalGpuMemoryInMiB")
            if total is None and info.get("Gpus"):
                total = sum(g.get("MemoryInfo", {}).get("SizeInMiB", 0) * g.get("Count", 0) for g in info["Gpus"])
            mem = round((total or 0) / 1024, 1)
    if model and model.lower().startswith(("inferentia", "trainium")):
        kind = "neuron"
    arch = "arm64" if (row.get("Arch") or "x86_64") == "arm64" else "x86_64"
    return [int(float(row["vCPUs"])), float(row["MemoryGiB"]), arch, count, model, mem, kind]


# ---------------------------------------------------------------- from dated snapshots (the shipped file)

# On-demand Linux prices read from skypilot-org/skypilot-catalog catalogs/v8/aws/vms.csv (the stored
# version at commit 00148f2af3672e2229b4f7bf8157d5a3f36e3c35), us-east-1 first: the region ratios below.
_SAMPLE_COMMIT = "00148f2af3672e2229b4f7bf8157d5a3f36e3c35"
_REGION_SAMPLES: Mapping[str, Mapping[str, float]] = {
    "m5a.large": {"us-east-1": 0.086, "ap-northeast-1": 0.112, "ap-northeast-2": 0.106, "ap-south-1": 0.056,
                  "ap-southeast-1": 0.108, "ap-southeast-2": 0.108, "ca-central-1": 0.096, "eu-central-1": 0.104,
                  "eu-south-1": 0.101, "eu-west-1": 0.096, "eu-west-2": 0.1, "eu-west-3": 0.101,
                  "us-east-2": 0.086, "us-west-1": 0.101, "us-west-2": 0.086},
    "c6id.large": {"us-east-1": 0.1008, "ap-northeast-1": 0.1281, "ap-northeast-2": 0.1155,
                   "ap-southeast-1": 0.1176, "ap-southeast-2": 0.1323, "ca-central-1": 0.1113,
                   "eu-central-1": 0.11655, "eu-south-1": 0.1197, "eu-west-1": 0.11445, "eu-west-2": 0.12075,
                   "eu-west-3": 0.12075, "us-east-2": 0.1008, "us-west-2": 0.1008},
    "c6in.12xlarge": {"us-east-1": 2.7216, "af-south-1": 3.65904, "ap-east-1": 3.6036, "ap-northeast-1": 3.4272,
                      "ap-northeast-2": 3.0744, "ap-northeast-3": 3.4248, "ap-south-1": 2.7216,
                      "ap-southeast-1": 3.1248, "ap-southeast-2": 3.5532, "ap-southeast-3": 3.1248,
                      "ap-southeast-4": 3.552, "ca-central-1": 2.9736, "eu-central-1": 3.0996,
                      "eu-north-1": 2.9232, "eu-south-1": 3.2508, "eu-south-2": 3.072, "eu-west-1": 3.0744,
                      "eu-west-2": 3.2256, "eu-west-3": 3.2256, "me-central-1": 3.3792, "me-south-1": 3.3768,
                      "us-east-2": 2.7216, "us-west-1": 3.402, "us-west-2": 2.7216},
    "g6.2xlarge": {"us-east-1": 0.9776, "ap-northeast-1": 1.41781, "ap-northeast-2": 1.20208,
                   "ap-south-1": 1.1739, "ap-southeast-2": 1.27107, "ca-central-1": 1.08547,
                   "eu-central-1": 1.22249, "eu-north-1": 1.03688, "eu-south-2": 1.03008, "eu-west-2": 1.24095,
                   "eu-west-3": 1.24095, "me-central-1": 1.20043, "us-east-2": 0.9776},
    "t3.2xlarge": {"us-east-1": 0.3328, "af-south-1": 0.4339, "ap-east-1": 0.4672, "ap-northeast-1": 0.4352,
                   "ap-northeast-2": 0.416, "ap-northeast-3": 0.4352, "ap-south-1": 0.3584, "ap-southeast-1": 0.4224,
                   "ap-southeast-2": 0.4224, "ap-southeast-3": 0.4224, "ap-southeast-4": 0.4224,
                   "ca-central-1": 0.3712, "eu-central-1": 0.384, "eu-north-1": 0.3456, "eu-south-1": 0.3834,
                   "eu-south-2": 0.3648, "eu-west-1": 0.3648, "eu-west-2": 0.3776, "eu-west-3": 0.3776,
                   "me-central-1": 0.4013, "me-south-1": 0.4013, "us-east-2": 0.3328, "us-west-1": 0.3968,
                   "us-west-2": 0.3328},
    "t2.xlarge": {"us-east-1": 0.1856, "ap-northeast-1": 0.2432, "ap-northeast-2": 0.2304, "ap-northeast-3": 0.2432,
                  "ap-south-1": 0.1984, "ap-southeast-1": 0.2336, "ap-southeast-2": 0.2336, "ca-central-1": 0.2048,
                  "eu-central-1": 0.2144, "eu-west-1": 0.2016, "eu-west-2": 0.2112, "eu-west-3": 0.2112,
                  "us-east-2": 0.1856, "us-west-1": 0.2208, "us-west-2": 0.1856},
    "g6.24xlarge": {"us-east-1": 6.6752, "eu-central-1": 8.34732, "eu-north-1": 7.07996, "eu-south-2": 7.03351,
                    "eu-west-2": 8.47339, "eu-west-3": 8.47339, "me-central-1": 8.19669, "us-east-2": 6.6752,
                    "us-west-2": 6.6752},
}


def region_ratios(samples: Mapping[str, Mapping[str, float]] = _REGION_SAMPLES) -> dict[str, float]:
    """Each region's median on-demand price relative to us-east-1 over the sampled types."""
    ratios: dict[str, list[float]] = {}
    for prices in samples.values():
        base = prices["us-east-1"]
        for region, value in prices.items():
            ratios.setdefault(region, []).append(value / base)
    return {r: round(statistics.median(v), 4) for r, v in ratios.items()}


_KARPENTER_TYPE = re.compile(r'"([a-z0-9-]+\.[a-z0-9-]+)":\s*([0-9.]+)')


def karpenter_prices(text: str) -> dict[str, float]:
    """us-east-1 on-demand prices from Karpenter's generated ``InitialOnDemandPricesAWS``."""
    body = text.split('"us-east-1": {', 1)[1].split("\n\t},", 1)[0]
    return {name: float(value) for name, value in _KARPENTER_TYPE.findall(body) if float(value) > 0}


def from_snapshots(*, moto: str | Path, karpenter_prices_go: str | Path, spot_advisor: str | Path,
                   older_moto: str | Path | None = None) -> Builder:
    """The shipped catalogue: see the module docstring for what each input is and how old.
    ``older_moto`` (moto 5.0.28's resources) adds the previous generations AWS has since stopped
    listing (p2, p3, g4ad, f1, dl1, ...), which users still name."""
    moto = Path(moto)
    b = Builder(provenance={
        "built": "2026-11-26", "how": "fogiac.targets.aws.refresh.from_snapshots",
        "note": "Hardware and availability are AWS API answers; us-east-1 on-demand is the Price List; "
                "other regions' on-demand and all spot prices are estimates (flagged per source). "
                "Run `fogiac catalog update` with credentials for the account's own prices.",
        "inputs": [
            {"what": "hardware, availability", "package": "moto-ext 5.1.54 (PyPI)", "license": "Apache-2.0",
             "files": ["moto/ec2/resources/instance_types.json.gz",
                       "moto/ec2/resources/instance_type_offerings/region/*.json.gz",
                       "moto/ec2/resources/instance_type_offerings/availability-zone/*.json.gz"]},
            {"what": "previous generations' hardware, availability", "package": "moto 5.0.28 (PyPI, 2025-02-02)",
             "license": "Apache-2.0", "files": ["moto/ec2/resources/instance_types.json.gz",
                                              "moto/ec2/resources/instance_type_offerings/region/*.json.gz"]},
            {"what": "us-east-1 on-demand", "repo": "aws/karpenter-provider-aws", "license": "Apache-2.0",
             "commit": "1d927085dd81a9df9301e613f371dac5b4d16bfe",
             "path": "pkg/providers/pricing/zz_generated.pricing_aws.go", "date": "2026-07-20"},
            {"what": "regional price ratios", "repo": "skypilot-org/skypilot-catalog", "license": _SKYPILOT_LICENSE,
             "commit": _SAMPLE_COMMIT, "path": "catalogs/v8/aws/vms.csv",
             "rows": {t: sorted(p) for t, p in _REGION_SAMPLES.items()}},
            {"what": "spot saving", "repo": "alexei-led/spotinfo", "license": "Apache-2.0 (data: AWS Spot "
             "Instance Advisor feed)", "commit": "5eedf20a99614443af215f4aaf09bd10805cac72",
             "path": "internal/spot/data/spot-advisor-data.json", "date": "2025-06-28"},
        ]})
    hw = b.source(Source("AWS DescribeInstanceTypes / DescribeInstanceTypeOfferings, as recorded in moto-ext 5.1.54",
                         "2026", "moto/ec2/resources (per region)", "Apache-2.0"))
    od = b.source(Source("AWS Price List API via aws/karpenter-provider-aws zz_generated.pricing_aws.go",
                         "2026-07-20", "us-east-1, Linux, shared tenancy, on-demand", "Apache-2.0"))
    est = b.source(Source("estimate: us-east-1 price x the region's median price ratio", "2026-07-20",
                          f"ratios from skypilot-org/skypilot-catalog vms.csv at {_SAMPLE_COMMIT[:12]}",
                          _SKYPILOT_LICENSE, estimate=True))
    spot_src = b.source(Source("estimate: on-demand x (1 - the Spot Instance Advisor's saving)", "2025-06-28",
                               "spot-advisor-data.json field 's', snapshot in alexei-led/spotinfo 5eedf20",
                               "Apache-2.0", estimate=True))
    for record in json.loads(gzip.decompress((moto / "instance_types.json.gz").read_bytes())).values():
        b.add_hardware(record, hw)
    for f in sorted((moto / "instance_type_offerings" / "region").glob("*.json.gz")):
        for item in json.loads(gzip.decompress(f.read_bytes())):
            if item["InstanceType"] in b.hardware:
                b.offer(item["InstanceType"], item["Location"])
    if older_moto is not None:
        older = Path(older_moto)
        old_hw = b.source(Source("AWS DescribeInstanceTypes / DescribeInstanceTypeOfferings, as recorded in "
                                 "moto 5.0.28", "2025-02-02", "previous generations no longer listed since; "
                                 "AWS may have retired them in some regions", "Apache-2.0"))
        added = set()
        for record in json.loads(gzip.decompress((older / "instance_types.json.gz").read_bytes())).values():
            if record["InstanceType"] not in b.hardware:
                b.add_hardware(record, old_hw)
                added.add(record["InstanceType"])
        for f in sorted((older / "instance_type_offerings" / "region").glob("*.json.gz")):
            for item in json.loads(gzip.decompress(f.read_bytes())):
                if item["InstanceType"] in added:
                    b.offer(item["InstanceType"], item["Location"])
    for name, by_region in moto_zones(moto).items():
        if name in b.hardware:
            b.zones[name] = by_region
    base = karpenter_prices(Path(karpenter_prices_go).read_text())
    ratios = region_ratios()
    for name, regions in b.offered.items():
        if name not in base:
            continue
        for region in regions:
            if region == "us-east-1":
                b.on_demand[(name, region)] = (base[name], od)
            elif region in ratios:
                b.on_demand[(name, region)] = (round(base[name] * ratios[region], 5), est)
    advisor = json.loads(Path(spot_advisor).read_text())["spot_advisor"]
    for region, by_os in advisor.items():
        for name, facts in by_os.get("Linux", {}).items():
            price = b.on_demand.get((name, region))
            if price is not None and region in b.offered.get(name, ()):
                b.spot[(name, region)] = (round(price[0] * (100 - int(facts["s"])) / 100, 5), spot_src)
    return b


def main(argv: Iterable[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m fogiac.targets.aws.refresh")
    parser.add_argument("--out", required=True)
    parser.add_argument("--from-csv")
    parser.add_argument("--source-commit", default="unknown")
    parser.add_argument("--source-date", default="unknown")
    parser.add_argument("--from-snapshots", action="store_true")
    parser.add_argument("--moto")
    parser.add_argument("--older-moto")
    parser.add_argument("--karpenter-prices")
    parser.add_argument("--spot-advisor")
    args = parser.parse_args(list(argv) if argv is not None else None)
    if args.from_csv:
        builder = from_skypilot_csv(args.from_csv, commit=args.source_commit, date=args.source_date)
    elif args.from_snapshots:
        builder = from_snapshots(moto=args.moto, karpenter_prices_go=args.karpenter_prices,
                                 spot_advisor=args.spot_advisor, older_moto=args.older_moto)
    else:
        parser.error("give --from-csv or --from-snapshots (the AWS path is `fogiac catalog update`)")
    out = builder.write(args.out)
    print(f"{out}: {len(builder.hardware)} types, {out.stat().st_size} bytes")


if __name__ == "__main__":
    main()
