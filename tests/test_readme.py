"""The README's manifest reference is generated from the model; this keeps the two in sync."""

from __future__ import annotations

from fogiac.manifest.reference import BEGIN, END, manifest_reference

from .conftest import REPO


def test_readme_reference_matches_the_model() -> None:
    text = (REPO / "README.md").read_text()
    block = text[text.index(BEGIN): text.index(END) + len(END)]
    assert block == manifest_reference(), "run: python -m fogiac.manifest.reference --write README.md"


def test_every_model_field_is_documented() -> None:
    reference = manifest_reference()
    for line in reference.splitlines():
        if line.startswith("| `"):
            assert not line.rstrip().endswith("|  |"), f"field without a description: {line}"


def test_ci_runs_the_readme_test_command() -> None:
    readme = (REPO / "README.md").read_text()
    assert "bash .ci/test" in readme and "bash .ci/demo" in readme
    assert "bash .ci/test" in (REPO / ".ci" / "run").read_text()
