"""The cost guide's forgotten-stack table (docs/guides/cost.md) comes from the catalogue; this keeps them in sync."""

from __future__ import annotations

import pytest

from fogiac.targets.aws.forgotten import BEGIN, END, Forgotten, readme_table
from tests.conftest import EXAMPLES, REPO


def test_readme_cost_table_matches_the_catalogue() -> None:
    text = (REPO / "docs" / "guides" / "cost.md").read_text()
    block = text[text.index(BEGIN): text.index(END) + len(END)]
    assert block == readme_table(EXAMPLES), "run: python -m fogiac.targets.aws.forgotten --write docs/guides/cost.md"


@pytest.mark.parametrize(("hours", "without", "with_autostop"), [
    (0.25, 1.045, 1.045),  # within the idle time autostop changes nothing
    (24, 100.32, 4.08 * 0.5 + 0.1 * 24),  # a day: half an hour of the instance, then the association alone
    (730, 4.18 * 730, 4.08 * 0.5 + 0.1 * 730),
])
def test_autostop_bills_the_idle_time_once_then_only_the_network(hours: float, without: float,
                                                                 with_autostop: float) -> None:
    motion = Forgotten("motion-planning.yaml", "c5.24xlarge", instances_usd_per_hour=4.08,
                       network_usd_per_hour=0.1, idle_hours=0.5)
    assert motion.without_autostop(hours) == pytest.approx(without)
    assert motion.with_autostop(hours) == pytest.approx(with_autostop)
