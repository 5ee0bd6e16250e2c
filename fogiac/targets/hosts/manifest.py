"""The ``hosts`` variant of the manifest's ``cloud:`` block.

Its machines are named, sized and priced in the default provider's terms (the same manifest runs
on every target, and ``plan`` shows what the nodes would cost in the cloud), so it answers as
that variant does, found through the plug-in registry rather than imported.
"""

from __future__ import annotations

from fogiac.manifest.clouds import DEFAULT, CloudVariant, variant

CLOUD: CloudVariant = variant(DEFAULT)
