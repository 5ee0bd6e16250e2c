"""The README is the front page and docs/ the site: the generated reference pages match the code,
the README stays short, keeps the two commands CI depends on, and links only to pages that exist."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from fogiac import registry
from fogiac.cli._reference import BEGIN as CLI_BEGIN
from fogiac.cli._reference import END as CLI_END
from fogiac.cli._reference import cli_reference
from fogiac.manifest.reference import BEGIN, END, manifest_reference

from .conftest import REPO

DOCS = REPO / "docs"


def _block(text: str, begin: str, end: str) -> str:
    return text[text.index(begin): text.index(end) + len(end)]


def test_manifest_reference_page_matches_the_model() -> None:
    text = (DOCS / "reference" / "manifest.md").read_text()
    assert _block(text, BEGIN, END) == manifest_reference(), \
        "run: python -m fogiac.manifest.reference --write docs/reference/manifest.md"


def _declared_verbs() -> set[str]:
    """The verbs pyproject.toml declares (its ``fogiac.commands`` entry points)."""
    text = (REPO / "pyproject.toml").read_text()
    section = text[text.index('[project.entry-points."fogiac.commands"]'):].split("\n[", 1)[0]
    return set(re.findall(r"^(\w+) = ", section, flags=re.M))


@pytest.mark.skipif(set(registry.names("fogiac.commands", own=True)) != _declared_verbs(),
                    reason="the installed entry points differ from pyproject.toml's: rerun .ci/setup")
def test_cli_reference_page_matches_the_typer_app() -> None:
    text = (DOCS / "reference" / "cli.md").read_text()
    assert _block(text, CLI_BEGIN, CLI_END) == cli_reference(), \
        "run: python -m fogiac.cli._reference --write docs/reference/cli.md"
    for verb in _declared_verbs():
        assert f"### `fogiac {verb}`" in text, verb


def test_every_model_field_is_documented() -> None:
    reference = manifest_reference()
    for line in reference.splitlines():
        if line.startswith("| `"):
            assert not line.rstrip().endswith("|  |"), f"field without a description: {line}"


def test_ci_runs_the_readme_test_command() -> None:
    readme = (REPO / "README.md").read_text()
    assert "bash .ci/test     # sets everything up, then runs every test" in readme
    assert "bash .ci/demo     # sets everything up, then runs the main job (the motion-planning example)" in readme
    assert "bash .ci/test" in (REPO / ".ci" / "run").read_text()


def test_the_readme_is_a_front_page_whose_links_all_resolve() -> None:
    readme = (REPO / "README.md").read_text()
    assert len(readme.splitlines()) <= 150
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", readme)
    assert links
    for link in links:
        if not link.startswith("http"):
            assert (REPO / link).is_file(), link


def test_every_docs_page_is_in_the_sites_navigation() -> None:
    nav = (REPO / "mkdocs.yml").read_text()
    pages = sorted(str(p.relative_to(DOCS)) for p in DOCS.rglob("*.md"))
    assert pages and all(f": {page}" in nav for page in pages), [p for p in pages if f": {p}" not in nav]


def _manifests() -> list[tuple[str, str]]:
    """Every YAML block of the README and the site that is a whole manifest (has ``name:`` and ``nodes:``)."""
    found = []
    for page in [REPO / "README.md", *sorted(DOCS.rglob("*.md"))]:
        for block in re.findall(r"^```yaml\n(.*?)^```", page.read_text(), flags=re.M | re.S):
            if re.search(r"^name:", block, flags=re.M) and re.search(r"^nodes:", block, flags=re.M):
                found.append((str(page.relative_to(REPO)), block))
    return found


@pytest.mark.parametrize(("page", "text"), _manifests(), ids=[p for p, _ in _manifests()])
def test_every_manifest_the_docs_show_is_valid(page: str, text: str, tmp_path: Path) -> None:
    from fogiac.manifest.schema import load_manifest

    for key in re.findall(r"^\s*key: (\S+)", text, flags=re.M):  # a hosts manifest's key files must exist
        (tmp_path / key).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / key).write_text("not a real key\n")
    (tmp_path / "fogiac.yaml").write_text(text)
    assert load_manifest(tmp_path / "fogiac.yaml").nodes, page
