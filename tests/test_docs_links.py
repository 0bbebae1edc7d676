"""Every link between the user guide's pages (README.md, docs/*.md) reaches a
page that exists and, with a #fragment, a heading on it (GitHub's slugs): a
section lost in an edit (it happened once to ten sections of benchmarks.md,
with 31 links pointing at them) fails here."""
from __future__ import annotations

import glob
import os
import re

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LINK = re.compile(r"\]\(([^)\s#]*\.md)?(?:#([^)\s]+))?\)")


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces as dashes."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def anchors(path: str) -> set[str]:
    out, fenced = set(), False
    for line in open(path, encoding="utf-8"):
        if line.startswith("```"):
            fenced = not fenced
        m = None if fenced else re.match(r"#{1,6}\s+(.*)", line)
        if m:
            out.add(slug(m.group(1)))
    return out


def broken_links(pages: list[str]) -> list[str]:
    bad = []
    for page in pages:
        text = open(page, encoding="utf-8").read()
        for m in LINK.finditer(text):
            target, frag = m.group(1), m.group(2)
            if (target is None and frag is None) or (target and "://" in target):
                continue
            path = os.path.normpath(os.path.join(os.path.dirname(page), target)) if target else page
            if not os.path.exists(path):
                bad.append(f"{os.path.relpath(page, ROOT)}: {target} does not exist")
            elif frag and frag not in anchors(path):
                bad.append(f"{os.path.relpath(page, ROOT)}: {target or ''}#{frag} is no heading")
    return bad


def test_every_guide_link_reaches_its_page_and_heading():
    pages = [os.path.join(ROOT, "README.md")] + sorted(glob.glob(os.path.join(ROOT, "docs", "*.md")))
    assert broken_links(pages) == []


def test_the_check_catches_a_lost_heading(tmp_path):
    a, b = tmp_path / "a.md", tmp_path / "b.md"
    a.write_text("# A\n\nSee [x](b.md#kept-one), [y](b.md#gone), [z](c.md), [w](#a).\n")
    b.write_text("# B\n\n## Kept one\n")
    assert broken_links([str(a), str(b)]) == [f"{os.path.relpath(str(a), ROOT)}: b.md#gone is no heading",
                                              f"{os.path.relpath(str(a), ROOT)}: c.md does not exist"]


def test_the_readme_is_short_and_gives_the_two_commands_first():
    """The README stays a front page (at most 150 lines; the figures live in
    docs/benchmarks.md) whose first 40 lines give the two set-up commands that
    .ci/run and a newcomer rely on."""
    lines = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read().splitlines()
    assert len(lines) <= 150, len(lines)
    head = "\n".join(lines[:40])
    assert "bash scripts/editor.sh" in head and "bash scripts/test.sh" in head
    ci = open(os.path.join(ROOT, ".ci", "run"), encoding="utf-8").read()
    assert "bash scripts/test.sh" in ci  # CI runs the README's test command


def test_how_it_works_names_every_module():
    """docs/how-it-works.md's module table names every source file of the
    package: by its path in a row's first cell, or by its name in backquotes in
    the row of a folder it is in (``infinitex/cli/``: `surface.py`)."""
    import re
    doc = open(os.path.join(ROOT, "docs", "how-it-works.md"), encoding="utf-8").read()
    rows = [line.split("|")[1:3] for line in doc.splitlines() if line.startswith("| `infinitex")]
    missing = []
    for folder, _, files in os.walk(os.path.join(ROOT, "infinitex")):
        for name in files:
            if not name.endswith(".py") or name == "__init__.py":
                continue
            rel = os.path.relpath(os.path.join(folder, name), ROOT).replace(os.sep, "/")
            named = False
            for first, text in rows:
                heads = re.findall(r"`([^`]+)`", first)
                if rel in heads or any(h.endswith("/") and rel.startswith(h) and f"`{rel[len(h):]}`" in text
                                       or h.endswith("/") and rel.startswith(h) and f"`{name}`" in text
                                       and rel[len(h):].count("/") <= 1 for h in heads):
                    named = True
                    break
            if not named:
                missing.append(rel)
    assert not missing, "not in docs/how-it-works.md: " + ", ".join(sorted(missing))
