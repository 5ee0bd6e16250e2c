"""A workload's container recipe: its template rendered over defaults, unknown names refused."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from fogiac.errors import WorkloadError
from fogiac.render import render


def render_dockerfile(template: str, defaults: Mapping[str, Any], overrides: Mapping[str, Any]) -> str:
    """The Dockerfile text; ``overrides`` replace ``defaults`` and must name known variables."""
    unknown = sorted(set(overrides) - set(defaults))
    if unknown:
        raise WorkloadError(f"unknown Dockerfile variables {', '.join(unknown)}; valid: {', '.join(sorted(defaults))}")
    return render(template, **{**defaults, **overrides})
