"""A middleware defined only in the tests: each cloud host runs a beacon (a tiny TCP server) that beats
every ``beacon.interval_s`` seconds; the edge dials every host's beacon and counts the beats. It serves a
ROS distribution fogiac does not list (``lighthouse``) and owns the manifest's ``beacon:`` block. Nothing
in fogiac/ names it; the entry point below is its whole registration."""

from __future__ import annotations

from fogiac.middlewares import MiddlewareEntry

ENTRY = MiddlewareEntry(name="beacon", middleware="tests.plugins.beacon.middleware:BEACON",
                        deployment="tests.plugins.beacon.deploy:DEPLOYMENT")
ENTRY_POINTS = {"fogiac.middlewares": {"beacon": "tests.plugins.beacon:ENTRY"}}
