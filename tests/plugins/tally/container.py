"""The tally workload's container recipe: what ``fogiac.provision.workload.recipe`` asks of any workload."""

from __future__ import annotations

from typing import Any

DEFAULTS: dict[str, Any] = {"base_image": "python:3.11-slim", "pip_packages": ["tally-counter==0.1"]}
FLAVOURS: dict[str, dict[str, Any]] = {"ubuntu": {}, "debian": {}}


def requirements() -> list[str]:
    return list(DEFAULTS["pip_packages"])


def dockerfile(**overrides: Any) -> str:
    unknown = sorted(set(overrides) - set(DEFAULTS))
    if unknown:
        raise ValueError(f"unknown recipe settings: {', '.join(unknown)}")
    settings = {**DEFAULTS, **overrides}
    return f"FROM {settings['base_image']}\nRUN pip install {' '.join(settings['pip_packages'])}\n"
