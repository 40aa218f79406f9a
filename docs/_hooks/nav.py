"""MkDocs hook: pages that ``nav`` in mkdocs.yml does not list still get a place in it.

Pages are added by anyone (one Markdown file per topic); listing each in mkdocs.yml would
make every new page a merge conflict. So a page under ``results/`` that the nav leaves out
goes at the end of the "Results" section, one under ``reference/`` at the end of
"Reference", and any other at the end of "How-to guides" (sorted by path). List a page in
mkdocs.yml only to give it a place of its own.
"""

from __future__ import annotations

from itertools import pairwise

from mkdocs.structure.nav import Section

_HOMES = {"results/": "Results", "reference/": "Reference"}
_DEFAULT = "How-to guides"


def _section(items, title: str):
    for item in items:
        if isinstance(item, Section) and item.title == title:
            return item
    return None


def on_nav(nav, config, files):  # noqa: ARG001 (hook API)
    listed = set(id(p) for p in nav.pages)
    for file in sorted(files.documentation_pages(), key=lambda f: f.src_uri):
        page = file.page
        if page is None or id(page) in listed or not file.inclusion.is_in_nav():
            continue
        home = next((t for d, t in _HOMES.items() if file.src_uri.startswith(d)), _DEFAULT)
        section = _section(nav.items, home)
        if section is None:
            section = Section(home, [])
            nav.items.append(section)
        section.children.append(page)
        page.parent = section
        nav.pages.append(page)
    for prev, nxt in pairwise(nav.pages):
        prev.next_page, nxt.previous_page = nxt, prev
    return nav
