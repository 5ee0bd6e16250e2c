"""The engine's tests run without the Pulumi CLI, or with a fake one (tests/support/pulumi.py)."""

from tests.support.pulumi import no_pulumi, pinned_pulumi

__all__ = ["no_pulumi", "pinned_pulumi"]
