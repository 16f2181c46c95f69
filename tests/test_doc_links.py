"""The documents' relative links: each names a file of the checkout and, after '#', one of its
headings as GitHub anchors them (text moved between documents left links pointing nowhere)."""

import re
import unicodedata
from collections import Counter
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
DOCUMENTS = [ROOT / "README.md", ROOT / "BENCHMARKS.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"\]\(([^)\s]+)\)")  # [text](target)
FENCE = re.compile(r"^```.*?^```", re.S | re.M)


def _kept(c: str) -> bool:
    """Whether GitHub keeps character `c` in a heading's anchor: letters, marks, decimal digits,
    '_', '-' and spaces (so not '²' or '½', which Python's \\w keeps)."""
    category = unicodedata.category(c)
    return c in "- " or category[0] in "LM" or category in ("Nd", "Pc")


def anchors(markdown: str) -> set[str]:
    """GitHub's anchors of a document's headings: lower case, the characters it drops
    (`_kept`) dropped, spaces as '-', a repeated one numbered -1, -2, ..."""
    seen, found = Counter(), set()
    for heading in re.findall(r"^#+ (.*)$", FENCE.sub("", markdown), re.M):
        slug = "".join(c for c in heading.strip().lower() if _kept(c)).replace(" ", "-")
        found.add(slug if not seen[slug] else f"{slug}-{seen[slug]}")
        seen[slug] += 1
    return found


def test_anchors_as_github_makes_them():
    text = "# RUN/eval.json and `x`\n## Tables 1–3\n## Tables 1–3\n```\n# not a heading\n```\n"
    assert anchors(text) == {"runevaljson-and-x", "tables-13", "tables-13-1"}
    assert anchors("## 256² — 250×400, λ (é)\n") == {"256--250400-λ-é"}


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: p.name)
def test_relative_links_resolve(document):
    text = FENCE.sub("", document.read_text(encoding="utf-8"))
    broken = []
    for target in LINK.findall(text):
        if re.match(r"[a-z]+:", target):  # https:, mailto:
            continue
        path, _, anchor = target.partition("#")
        linked = (document.parent / path).resolve() if path else document
        if not linked.exists():
            broken.append(f"{target}: no such file")
        elif anchor and linked.suffix == ".md":
            if anchor not in anchors(linked.read_text(encoding="utf-8")):
                broken.append(f"{target}: no such heading")
    assert not broken, f"{document.name}: {broken}"
