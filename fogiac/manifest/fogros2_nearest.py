"""Which of the regions a FogROS2 launch file lists is nearest the operator, decided offline.

FogROS2's ``find_nearest_region_and_ami(regions)`` asks web services for the robot's public address and
its place at launch time, and takes the listed region at the least great-circle distance. fogiac reads
the launch file offline and asks no web service, so the operator's place is this machine's time zone
(``TZ``, else the ``/etc/localtime`` link, else ``/etc/timezone``), which the system's time zone table
(``zone1970.tab``, ``zone.tab``) places at its principal city. A zone the table does not place (UTC, a
server's usual) leaves the place unknown: then the first region listed is taken, and the note says so.
Either way the note names the choice, for the operator to change.
"""

from __future__ import annotations

import math
import os
import re
import zoneinfo
from pathlib import Path

# Where each region's data centres are, near enough to rank them (degrees north, east): the city or
# area AWS names for the region.
PLACES: dict[str, tuple[float, float]] = {
    "us-east-1": (39.04, -77.49), "us-east-2": (39.96, -83.00), "us-west-1": (37.77, -122.42),
    "us-west-2": (45.84, -119.70), "ca-central-1": (45.50, -73.57), "ca-west-1": (51.05, -114.07),
    "mx-central-1": (20.59, -100.39), "sa-east-1": (-23.55, -46.63), "af-south-1": (-33.92, 18.42),
    "eu-west-1": (53.35, -6.26), "eu-west-2": (51.51, -0.13), "eu-west-3": (48.86, 2.35),
    "eu-central-1": (50.11, 8.68), "eu-central-2": (47.38, 8.54), "eu-south-1": (45.46, 9.19),
    "eu-south-2": (41.65, -0.88), "eu-north-1": (59.33, 18.07), "il-central-1": (32.09, 34.78),
    "me-south-1": (26.23, 50.59), "me-central-1": (25.20, 55.27), "ap-south-1": (19.08, 72.88),
    "ap-south-2": (17.39, 78.49), "ap-east-1": (22.32, 114.17), "ap-east-2": (25.03, 121.56),
    "ap-northeast-1": (35.68, 139.69), "ap-northeast-2": (37.57, 126.98), "ap-northeast-3": (34.69, 135.50),
    "ap-southeast-1": (1.35, 103.82), "ap-southeast-2": (-33.87, 151.21), "ap-southeast-3": (-6.21, 106.85),
    "ap-southeast-4": (-37.81, 144.96), "ap-southeast-5": (3.14, 101.69), "ap-southeast-6": (-36.85, 174.76),
    "ap-southeast-7": (13.76, 100.50),
}
_COORDS = re.compile(r"^([+-])(\d\d)(\d\d)(\d\d)?([+-])(\d\d\d)(\d\d)(\d\d)?$")  # ISO 6709, as the tables write it


def local_zone() -> str | None:
    """This machine's time zone name (``Europe/Paris``), or None."""
    given = os.environ.get("TZ", "").lstrip(":")
    if given:
        return given.split("zoneinfo/", 1)[-1]
    try:
        link = os.readlink("/etc/localtime")
    except OSError:
        link = ""
    if "zoneinfo/" in link:
        return link.split("zoneinfo/", 1)[1]
    try:
        return Path("/etc/timezone").read_text(encoding="utf-8").strip() or None
    except (OSError, UnicodeDecodeError):
        return None


def zone_place(zone: str) -> tuple[float, float] | None:
    """Where the time zone table puts ``zone``'s principal city, or None (UTC, an unknown name, no table)."""
    for folder in zoneinfo.TZPATH:
        for table in ("zone1970.tab", "zone.tab"):
            try:
                text = (Path(folder) / table).read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError):
                continue
            for line in text.splitlines():
                fields = line.split("\t")
                if len(fields) >= 3 and fields[2] == zone and (match := _COORDS.match(fields[1])):
                    return _degrees(match.group(1, 2, 3, 4)), _degrees(match.group(5, 6, 7, 8))
    return None


def _degrees(parts: tuple[str, ...]) -> float:
    sign, whole, minutes, seconds = parts
    value = int(whole) + int(minutes) / 60 + int(seconds or 0) / 3600
    return -value if sign == "-" else value


def _km(a: tuple[float, float], b: tuple[float, float]) -> float:
    """Great-circle distance (haversine)."""
    lat1, lon1, lat2, lon2 = map(math.radians, (*a, *b))
    h = math.sin((lat2 - lat1) / 2) ** 2 + math.cos(lat1) * math.cos(lat2) * math.sin((lon2 - lon1) / 2) ** 2
    return 2 * 6371 * math.asin(math.sqrt(h))


def nearest(regions: list[str], *, zone: str | None) -> tuple[str, str]:
    """The region to use among ``regions`` (as listed, at least one) and the header's note saying why."""
    listed = ", ".join(regions)
    said = (f"cloud.region: FogROS2 picked the region nearest the robot at launch time among {listed} "
            "(find_nearest_region_and_ami)")
    place = zone_place(zone) if zone else None
    placed = [r for r in regions if r in PLACES]
    if place is None or not placed:
        why = (f"this machine's time zone ({zone}) does not say where it is" if zone and place is None
               else "no time zone is set here" if not zone else "fogiac does not know where those regions are")
        return regions[0], f"{said}; fogiac uses the first, {regions[0]}: set yours ({why})"
    chosen = min(placed, key=lambda r: _km(place, PLACES[r]))
    return chosen, (f"{said}; fogiac uses {chosen}, the nearest to this machine's time zone ({zone}): "
                    "set yours if the robot is elsewhere")
