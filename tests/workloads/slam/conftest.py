"""Rendered sequences shared by the SLAM tests: rendered once per session, at half fr1 resolution.

Half resolution (320 x 240, fr1's camera scaled) keeps the suite within a couple of minutes on
two cores; the benchmark and README figures use full 640 x 480 frames, and so does the monocular
test: at half resolution two-view triangulation leaves too few points (measured 5-13 cm ATE
where full frames give 2.1 cm).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from workloads.slam.camera import Intrinsics
from workloads.slam.render import render_sequence

SCALE = 0.5
FEATURES = 600  # per 320 x 240 frame


@pytest.fixture(scope="session")
def desk(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("desk")
    render_sequence(out, kind="desk", frames=120, intrinsics=Intrinsics.fr1().scaled(SCALE))
    return out


@pytest.fixture(scope="session")
def desk_full(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("desk-full")
    render_sequence(out, kind="desk", frames=100)
    return out


@pytest.fixture(scope="session")
def loop(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("loop")
    render_sequence(out, kind="loop", frames=260, intrinsics=Intrinsics.fr1().scaled(SCALE))
    return out
