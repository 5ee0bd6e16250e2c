"""examples/ci: the workflows users' CI runs: plan on a pull request (the real engine path, pulumi preview, runs
there), apply exactly the reviewed plan on merge."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import uuid
from pathlib import Path

import pytest
import yaml

from fogiac.pulumi_engine.workspace import PULUMI_CLI_VERSION
from tests.conftest import REPO

WORKFLOW = Path(__file__).parents[3] / "examples" / "ci" / "fogiac-plan.yml"
APPLY = WORKFLOW.with_name("fogiac-apply.yml")


def test_workflow_plans_on_pull_requests_and_previews_with_the_pinned_cli() -> None:
    doc = yaml.safe_load(WORKFLOW.read_text())
    assert "pull_request" in doc[True]  # YAML 1.1 reads the key `on` as True
    assert doc["env"]["PULUMI_VERSION"] == PULUMI_CLI_VERSION, "keep the workflow's pin equal to fogiac.pulumi_engine.workspace's"
    steps = doc["jobs"]["plan"]["steps"]
    # the saved plan fogiac-apply.yml applies, made against the deployed record
    assert any('fogiac plan "$MANIFEST" --env "$FOGIAC_ENV" --out plan.json --markdown > deployed.md' in step.get("run", "")
               for step in steps)
    # the comment is the diff against the pull request's base branch (rendered in tests/cli/test_plan_diff.py)
    assert any('--against "git:origin/$BASE_REF:$MANIFEST" --markdown > base.md' in step.get("run", "")
               for step in steps)
    preview = [s for s in steps if s.get("uses", "").startswith("pulumi/actions@")]
    assert [s["with"]["command"] for s in preview] == ["preview"]
    assert preview[0]["with"]["pulumi-version"] == "${{ env.PULUMI_VERSION }}"
    assert preview[0]["with"]["cloud-url"] == "${{ env.FOGIAC_STATE_URL }}"  # Pulumi's state beside fogiac's record


def test_apply_workflow_runs_on_merge_one_at_a_time_with_the_reviewed_plan() -> None:
    doc = yaml.safe_load(APPLY.read_text())
    assert doc[True]["push"]["branches"] == ["main"] and doc["concurrency"]["cancel-in-progress"] is False
    assert doc["env"]["PULUMI_VERSION"] == PULUMI_CLI_VERSION
    assert doc["env"]["FOGIAC_ENV"] == yaml.safe_load(WORKFLOW.read_text())["env"]["FOGIAC_ENV"]
    runs = [step.get("run", "") for step in doc["jobs"]["apply"]["steps"]]
    assert any('--name "fogiac-plan-$head"' in run for run in runs)  # the artifact fogiac-plan.yml uploads
    assert runs[-1] == 'fogiac up "$MANIFEST" --env "$FOGIAC_ENV" --plan reviewed/plan.json --yes'


# -- both workflows' fogiac commands, as written, against a shared store in LocalStack ----------------------

MANIFEST_V1 = """\
name: cilab
cloud: {{provider: local}}
edge: {{ros_master: "{edge}"}}
nodes:
  - {{name: worker, machine: t3.small, command: [sleep, "3600"]}}
"""
SECOND_NODE = '  - {name: helper, machine: t3.small, command: [sleep, "3600"]}\n'


def _step(path: Path, job: str, name: str) -> tuple[str, dict[str, str]]:
    """A step's shell script and its plain env (``${{ }}`` expressions are the runner's; the test sets those)."""
    doc = yaml.safe_load(path.read_text())
    (step,) = [s for s in doc["jobs"][job]["steps"] if s.get("name") == name]
    env = {k: str(v) for k, v in {**doc["env"], **step.get("env", {})}.items() if "${{" not in str(v)}
    return step["run"], env


def _run_step(path: Path, job: str, name: str, cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    script, step_env = _step(path, job, name)
    # GitHub's runner: bash --noprofile --norc -eo pipefail {0}
    return subprocess.run(["bash", "--noprofile", "--norc", "-eo", "pipefail", "-c", script], cwd=cwd,
                          env={**env, **step_env}, capture_output=True, text=True, timeout=600)


def _git(repo: Path, *argv: str) -> None:
    subprocess.run(["git", "-C", str(repo), *argv], check=True, capture_output=True,
                   env={**os.environ, "GIT_AUTHOR_NAME": "lab", "GIT_AUTHOR_EMAIL": "lab@example.org",
                        "GIT_COMMITTER_NAME": "lab", "GIT_COMMITTER_EMAIL": "lab@example.org"})


def _pull_request(repo: Path, manifest: str) -> None:
    """The pull request's head checked out, its base as ``origin/main`` (what actions/checkout gives)."""
    _git(repo, "update-ref", "refs/remotes/origin/main", "main")
    _git(repo, "checkout", "-q", "-B", "change", "main")
    (repo / "fogiac.yaml").write_text(manifest)
    _git(repo, "add", "fogiac.yaml")
    _git(repo, "commit", "-q", "-m", "the change under review")


def _merge(repo: Path) -> None:
    _git(repo, "checkout", "-q", "main")
    _git(repo, "merge", "-q", "--ff-only", "change")


@pytest.mark.localstack
@pytest.mark.ros
@pytest.mark.timeout(900)
def test_the_workflows_plan_against_the_deployed_record_and_apply_exactly_the_reviewed_plan(
        aws_env: str, tmp_path: Path) -> None:
    """Issue 33: a pull request's plan job compares with the record a member deployed (in the shared
    store, not the runner's disk) and saves its plan; the apply job's ``fogiac up --plan`` applies that
    plan, and refuses it once the record has moved on. The ``local`` target stands in for the cloud; the
    download of the artifact (``gh run download``) is a copy here."""
    import boto3

    from tests.support.ros import ros_missing, roscore

    if why := ros_missing():
        pytest.skip(why)
    bucket = f"fogiac-ci-{uuid.uuid4().hex[:10]}"
    boto3.client("s3").create_bucket(Bucket=bucket, CreateBucketConfiguration={"LocationConstraint": "us-west-2"})
    repo = tmp_path / "repo"
    repo.mkdir()
    _git(repo, "init", "-q", "-b", "main")
    (repo / "README.md").write_text("the lab's robot\n")
    _git(repo, "add", "README.md")
    _git(repo, "commit", "-q", "-m", "start")
    with roscore(tmp_path / "robot") as robot:  # the robot's own master, which up connects the stack to
        v1 = MANIFEST_V1.format(edge=robot["ROS_MASTER_URI"])
        runner = {**os.environ, "FOGIAC_STATE_URL": f"s3://{bucket}/lab", "FOGIAC_STATE_PASSPHRASE": "lab secret",
                  "FOGIAC_STATE_DIR": str(tmp_path / "runner-state"), "BASE_REF": "main", "PYTHONPATH": str(REPO),
                  "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}  # this fogiac
        plan_step = (WORKFLOW, "plan", "fogiac plan against the deployed record and the base branch")
        apply_step = (APPLY, "apply", "fogiac up --plan (exactly what was reviewed, under the stack's lock)")

        def review() -> tuple[str, bytes]:
            done = _run_step(*plan_step, repo, runner)
            assert done.returncode == 0, done.stdout + done.stderr
            return (repo / "comment.md").read_text(), (repo / "plan.json").read_bytes()

        def apply(plan: bytes) -> subprocess.CompletedProcess[str]:
            (repo / "reviewed").mkdir(exist_ok=True)
            (repo / "reviewed" / "plan.json").write_bytes(plan)  # the artifact, as gh run download leaves it
            return _run_step(*apply_step, repo, {**runner, "FOGIAC_STATE_DIR": str(tmp_path / "apply-state")})

        try:
            _pull_request(repo, v1)  # the pull request that adds the manifest
            comment, first = review()
            deployed, base = comment.split("#### Against main")
            assert deployed.startswith("#### Merging this changes what is deployed") and "worker" in deployed, comment
            _merge(repo)
            applied = apply(first)
            assert applied.returncode == 0, applied.stdout + applied.stderr

            _pull_request(repo, v1 + SECOND_NODE)  # the next pull request adds a node
            comment, second = review()
            deployed, base = comment.split("#### Against main")
            # against what runs (read from the store by another machine's runner): only the new node
            assert "helper" in deployed and "Plan: 0 to add, 0 to change, 0 to destroy." not in deployed, comment
            assert "helper" in base, comment
            _merge(repo)
            applied = apply(second)
            assert applied.returncode == 0, applied.stdout + applied.stderr
            shown = subprocess.run([sys.executable, "-m", "fogiac", "status", "fogiac.yaml", "--env", "ci", "--json"],
                                   cwd=repo, env={**runner, "FOGIAC_STATE_DIR": str(tmp_path / "third")},
                                   capture_output=True, text=True, timeout=300)
            assert shown.returncode == 0, shown.stdout + shown.stderr
            nodes = {n["node"] for h in json.loads(shown.stdout)["hosts"] for n in h["nodes"]}
            assert nodes == {"worker", "helper"}, shown.stdout

            again = apply(second)  # the same reviewed plan once more: the record has moved on since
            assert again.returncode != 0
            assert re.fullmatch(r"error: saved plan reviewed/plan\.json was made against serial \d+ \(lineage \w+\) of "
                                r"stack cilab-ci's record, which is now serial \d+ .*; run `fogiac plan --out` again",
                                again.stderr.strip().splitlines()[-1]), again.stderr
        finally:
            subprocess.run([sys.executable, "-m", "fogiac", "down", "fogiac.yaml", "--env", "ci", "--yes"], cwd=repo,
                           env=runner, capture_output=True, timeout=300)
