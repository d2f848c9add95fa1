"""The companion site (``make site``): the results page and the executed notebooks of ``make
reproduce`` as static HTML, the figures beside them; nothing is run again. nbconvert renders both
(the page as one Markdown cell), so tables, math and figures look alike; each heading also gets
the anchor GitHub gives it, so the links between the page, the notebooks and the README's
block (``docs/results.md#...``) hold in the site too.

    python -m softflow.report.site [--notebooks DIR] [--out DIR]
"""

from __future__ import annotations

import argparse
import re
import shutil
from pathlib import Path

import jinja2
import nbformat
from bs4 import BeautifulSoup
from nbconvert import HTMLExporter

from softflow.report.sections import TEMPLATES
from softflow.store import REPO, write_text

RESULTS = "results.html"


def github_anchor(heading: str) -> str:
    """The anchor GitHub gives a Markdown heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _html(notebook: nbformat.NotebookNode, title: str) -> str:
    """A notebook as one HTML page (its outputs as they are), every heading with its GitHub anchor
    and links to docs/results.md pointing at the site's page."""
    notebook.metadata["title"] = title
    body, _ = HTMLExporter(template_name="lab").from_notebook_node(notebook)
    soup = BeautifulSoup(body, "html.parser")
    for heading in soup.find_all(re.compile(r"^h[1-6]$")):
        text = heading.get_text().removesuffix("¶")
        heading.insert(0, soup.new_tag("a", id=github_anchor(text)))
    for link in soup.find_all("a", href=True):
        link["href"] = re.sub(r"^(\.\./)?docs/results\.md", lambda m: "../" * bool(m.group(1)) + RESULTS, link["href"])
    return str(soup)


def build(notebooks: list[Path], results: Path, figures: Path, out: Path) -> list[Path]:
    """The site in ``out``: index.html, the results page (``results``, Markdown whose figures are
    under ``figures``), one page per notebook under notebooks/, the figures; returns the pages."""
    if not results.is_file():
        raise ValueError(f"no results page {results}; run make reproduce (it writes docs/results.md)")
    if not notebooks:
        raise ValueError("no executed notebooks to show; run make reproduce (it writes build/notebooks/paper/)")
    out.mkdir(parents=True, exist_ok=True)
    shutil.copytree(figures, out / "figures", dirs_exist_ok=True, ignore=shutil.ignore_patterns("*.csv", "sweeps"))
    text = results.read_text().replace("](../figures/", "](figures/")
    page = nbformat.v4.new_notebook(cells=[nbformat.v4.new_markdown_cell(text)])
    pages = [out / RESULTS]
    write_text(pages[0], _html(page, "Results"))
    for path in notebooks:
        pages.append(out / "notebooks" / f"{path.stem}.html")
        pages[-1].parent.mkdir(exist_ok=True)
        write_text(pages[-1], _html(nbformat.read(path, as_version=4), path.stem))
    index = jinja2.Template((TEMPLATES / "site_index.html.j2").read_text(), autoescape=True)
    write_text(out / "index.html", index.render(results=RESULTS, notebooks=[p.relative_to(out) for p in pages[1:]]))
    return [out / "index.html", *pages]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--notebooks", type=Path, default=REPO / "build" / "notebooks" / "paper")
    parser.add_argument("--out", type=Path, default=REPO / "build" / "site")
    args = parser.parse_args()
    pages = build(sorted(args.notebooks.glob("*.ipynb")), REPO / "docs" / "results.md", REPO / "figures", args.out)
    print(f"{len(pages)} pages; open {pages[0]}")


if __name__ == "__main__":
    main()
