"""What a target is, as targets and their tests import it: the driver protocol and its records live
with the lifecycle that asks them (:mod:`fogiac.lifecycle.driver`), so the lifecycle imports no target."""

from fogiac.lifecycle.driver import (
    Check,
    Created,
    Destroyed,
    DownOptions,
    DownResult,
    Feature,
    Machine,
    Prepared,
    Reach,
    Refreshed,
    SweepOutcome,
    Target,
    UpOptions,
    UpResult,
)
from fogiac.state import untouched_on_failure

__all__ = ["Check", "Created", "Destroyed", "DownOptions", "DownResult", "Feature", "Machine", "Prepared", "Reach",
           "Refreshed", "SweepOutcome", "Target", "UpOptions", "UpResult", "untouched_on_failure"]
