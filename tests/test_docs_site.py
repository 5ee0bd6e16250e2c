"""Issue 35, item 25: the documentation site as a reader gets it, built once with mkdocs. No request leaves the
page (the theme fetched web fonts: offline, each page hung until the lookup failed); a site opened from disk
links page to page (it showed "Index of"); key names in tables stay whole, long code lines scroll, a shell
block's ``local`` is not coloured as a keyword; the project's own pages are not under "Reference"."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from tests.conftest import REPO

pytest.importorskip("mkdocs")
pytest.importorskip("material")


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("site") / "site"
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)], cwd=REPO,
                          env={**os.environ, "NO_MKDOCS_2_WARNING": "1"}, capture_output=True, text=True, timeout=600,
                          check=False)
    assert done.returncode == 0, done.stderr
    return out


def pages(site: Path) -> list[Path]:
    return sorted(p for p in site.rglob("*.html") if p.name != "404.html")


def test_no_page_asks_the_network_for_anything(site: Path) -> None:
    for page in pages(site):
        text = page.read_text()
        external = re.findall(r'<(?:link|script|img)[^>]*(?:href|src)="(https?://[^"]*)"', text)
        assert external == [], (page, external)
        assert "fonts.googleapis" not in text and "fonts.gstatic" not in text, page


def test_a_site_opened_from_disk_links_to_files(site: Path) -> None:
    for page in pages(site):
        for link in re.findall(r'<a [^>]*href="([^"#]+)(?:#[^"]*)?"', page.read_text()):
            if re.match(r"[a-z]+:", link):
                continue  # an outside link (https:, mailto:) is the reader's to follow
            target = (page.parent / link).resolve()
            assert target.is_file(), (page, link)  # never a folder, which file:// lists as "Index of"


def test_tables_code_and_shell_words_read_as_written(site: Path) -> None:
    css = (site / "stylesheets" / "extra.css").read_text()
    assert re.search(r"td code[^{]*\{[^}]*white-space: nowrap", css, re.S)
    assert re.search(r"pre > code\s*\{[^}]*overflow-x: auto", css, re.S)
    assert re.search(r"\.language-sh \.nb[^{]*\{[^}]*color: inherit", css, re.S)
    start = (site / "getting-started.html").read_text()
    assert 'stylesheets/extra.css"' in start
    assert '<span class="nb">local</span>' in start  # what the rule above makes plain


def test_reference_holds_the_references_only() -> None:
    nav = yaml.safe_load((REPO / "mkdocs.yml").read_text())["nav"]
    sections = {next(iter(item)): next(iter(item.values())) for item in nav if isinstance(item, dict)}
    reference = sections["Reference"]
    assert [next(iter(page.values())) for page in reference] == ["reference/manifest.md", "reference/cli.md"]
    top = [next(iter(item.values())) for item in nav if isinstance(next(iter(item.values())), str)]
    assert not {"security.md", "verified.md", "benchmarks.md", "contributing.md"} & set(top)
