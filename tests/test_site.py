"""The companion site opened in a real headless browser (Chromium through Playwright): a small site
of two committed notebooks and the results page must load without a page error, every image it
shows from the site must load, every link inside the site must reach a page and an anchor that
exist, and the results page must hold every table and figure of the Markdown it renders."""

import os
import re
import shutil
from pathlib import Path
from urllib.parse import unquote, urlparse

import pytest

from softflow.report import site
from softflow.store import REPO

NOTEBOOKS = ("08_honest_table1.ipynb", "16_closed_loop_recorded.ipynb")


def chromium() -> str:
    """The system's Chromium; CI installs it (.ci/run), a user's machine may lack it."""
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None:
        if os.environ.get("CI"):
            pytest.fail("no Chromium on the CI machine: .ci/run installs Debian's chromium package")
        pytest.skip("no Chromium here (apt-get install chromium): the site's browser test needs one")
    return found


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = tmp_path_factory.mktemp("site")
    notebooks = [REPO / "notebooks" / name for name in NOTEBOOKS]
    return out, site.build(notebooks, REPO / "docs" / "results.md", REPO / "figures", out)


@pytest.fixture(scope="module")
def browser():
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=chromium(), args=["--no-sandbox"])
        yield launched
        launched.close()


def opened(browser, path: Path) -> dict:
    """What the browser saw on the page at ``path``: its page errors, the site's requests that
    failed, its images (source, loaded), its links and the ids of its elements."""
    page = browser.new_page()
    errors, failed = [], []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.on("requestfailed", lambda request: failed.append(request.url) if request.url.startswith("file:") else None)
    page.goto(path.as_uri(), wait_until="load")
    seen = dict(
        errors=errors,
        failed=failed,
        images=page.eval_on_selector_all("img", "els => els.map(e => [e.src, e.complete && e.naturalWidth > 0])"),
        links=page.eval_on_selector_all("a[href]", "els => els.map(e => e.href)"),
        ids=set(page.eval_on_selector_all("[id]", "els => els.map(e => e.id)")),
        tables=page.eval_on_selector_all("table", "els => els.length"),
    )
    page.close()
    return seen


def test_every_page_loads_with_its_images_and_every_link_in_the_site_holds(built, browser):
    out, pages = built
    seen = {path: opened(browser, path) for path in pages}
    for path, page in seen.items():
        assert not page["errors"] and not page["failed"], f"{path.name}: {page['errors']} {page['failed']}"
        broken = [src for src, loaded in page["images"] if src.startswith("file:") and not loaded]
        assert not broken, f"{path.name}: images that did not load: {broken}"
        for link in page["links"]:
            target = urlparse(link)
            if target.scheme != "file":
                continue  # the web beyond the site
            file = Path(unquote(target.path))
            assert file.is_file() and out in file.parents, f"{path.name}: a link to a missing page {link}"
            if target.fragment and file in seen:  # as a browser looks an anchor up: as written, then decoded
                ids = seen[file]["ids"]
                assert {target.fragment, unquote(target.fragment)} & ids, f"{path.name}: no anchor for {link}"
    assert {path.name for path in pages} >= {"index.html", site.RESULTS, *(Path(n).stem + ".html" for n in NOTEBOOKS)}


def test_the_results_page_shows_every_table_and_figure_it_renders(built, browser):
    out, _ = built
    markdown = (REPO / "docs" / "results.md").read_text()
    page = opened(browser, out / site.RESULTS)
    tables = len(re.findall(r"^\|---", markdown, flags=re.M))
    figures = re.findall(r"!\[[^\]]*\]\(\.\./figures/([^)]+)\)", markdown)
    assert tables >= 10 and page["tables"] == tables
    shown = [Path(urlparse(src).path).name for src, loaded in page["images"] if loaded]
    assert figures and sorted(shown) == sorted(figures)
    assert {"ranking", "table1", "ambiguity", "loop"} <= page["ids"]  # the README's block links here
