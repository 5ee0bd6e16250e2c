"""The ``aws`` variant of the manifest's ``cloud:`` block: regions, zones and machine types from the EC2
catalogue in this folder (``data/instance_types.json``), read by the neutral catalogue format
(:class:`fogiac.catalogue.CatalogueCloud`). Named by the ``fogiac.clouds`` entry point; loading it
imports no SDK and nothing of the lifecycle."""

from __future__ import annotations

from fogiac.catalogue import CatalogueCloud

CLOUD = CatalogueCloud("targets/aws/data/instance_types.json")
