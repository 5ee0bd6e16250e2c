"""examples/ci: the workflow that runs the real engine path (pulumi preview) in users' CI."""

from __future__ import annotations

from pathlib import Path

import yaml

from fogiac.pulumi_engine.workspace import PULUMI_CLI_VERSION

WORKFLOW = Path(__file__).parents[3] / "examples" / "ci" / "fogiac-plan.yml"


def test_workflow_plans_on_pull_requests_and_previews_with_the_pinned_cli() -> None:
    doc = yaml.safe_load(WORKFLOW.read_text())
    assert "pull_request" in doc[True]  # YAML 1.1 reads the key `on` as True
    assert doc["env"]["PULUMI_VERSION"] == PULUMI_CLI_VERSION, "keep the workflow's pin equal to fogiac.pulumi_engine.workspace's"
    steps = doc["jobs"]["plan"]["steps"]
    assert any("fogiac plan" in step.get("run", "") and "--json" in step.get("run", "") for step in steps)
    # the comment is the diff against the pull request's base branch (rendered in tests/cli/test_plan_diff.py)
    assert any('--against "git:origin/$BASE_REF:$MANIFEST" --markdown > comment.md' in step.get("run", "")
               for step in steps)
    preview = [s for s in steps if s.get("uses", "").startswith("pulumi/actions@")]
    assert [s["with"]["command"] for s in preview] == ["preview"]
    assert preview[0]["with"]["pulumi-version"] == "${{ env.PULUMI_VERSION }}"
