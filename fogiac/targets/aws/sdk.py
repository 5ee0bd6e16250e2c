"""The aws target's SDKs (boto3, botocore, pulumi, pulumi_aws), imported where its work starts, through
:func:`fogiac.extras.need`: a missing one is one line naming the ``aws`` extra that installs it."""

from __future__ import annotations

from types import ModuleType

from fogiac import extras


def need(module: str) -> ModuleType:
    return extras.need(module, extra="aws")
