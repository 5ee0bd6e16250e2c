"""What fogiac chooses when a manifest does not say, named once.

A manifest without ``cloud.provider`` runs on :data:`PROVIDER`; everything else a default means
(its region, its network's ranges, its limits) is that provider's ``cloud:`` variant's to say
(:mod:`fogiac.manifest.clouds`), so the neutral core holds no cloud's names or numbers.
"""

from __future__ import annotations

PROVIDER = "aws"  # the ``fogiac.clouds`` entry point a manifest without ``provider:`` names
