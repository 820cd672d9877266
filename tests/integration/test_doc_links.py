"""Every relative link in README.md and docs/*.md reaches a file that exists and, where it names an anchor
(``#section``), a heading of that file: condensing a document must not break the links into it."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md")), REPO / "models" / "README.md"]
LINK = re.compile(r"\]\(([^()\s]*)\)")  # [text](target); targets here hold no spaces or brackets
FENCE = re.compile(r"^\s*```")
# a script or test a reader is told to run, named as a path from the repository root (in prose or a command)
RUNNABLE = re.compile(r"(?<![\w/.])((?:benchmarks|scripts|tests)/[\w./-]+\.(?:py|sh))")


def _prose(text: str) -> str:
    """The text outside fenced code blocks (a ``](x)`` inside a command is not a link)."""
    kept, inside = [], False
    for line in text.splitlines():
        if FENCE.match(line):
            inside = not inside
            continue
        if not inside:
            kept.append(line)
    return "\n".join(kept)


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped except hyphens, spaces to hyphens."""
    text = re.sub(r"`", "", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """Every heading anchor of a markdown file, with GitHub's -1, -2 ... for repeated headings."""
    seen: dict[str, int] = {}
    out = set()
    for line in _prose(path.read_text(encoding="utf-8")).splitlines():
        m = re.match(r"#{1,6}\s+(.*)", line)
        if not m:
            continue
        base = slug(m.group(1))
        n = seen.get(base, 0)
        seen[base] = n + 1
        out.add(base if n == 0 else f"{base}-{n}")
    return out


def test_slug_follows_github():
    assert slug("Hostile input, round 7 (fuzz7, 2026-11-29): today's surfaces") == (
        "hostile-input-round-7-fuzz7-2026-11-29-todays-surfaces"
    )
    assert slug("Relighting real photos: DPR's protocol") == "relighting-real-photos-dprs-protocol"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(REPO).as_posix())
def test_every_link_resolves(doc):
    broken = []
    for target in LINK.findall(_prose(doc.read_text(encoding="utf-8"))):
        if not target or re.match(r"[a-z][a-z0-9+.-]*:", target):  # a URL (http:, mailto:) is not checked here
            continue
        file_part, _, anchor = target.partition("#")
        dest = (doc.parent / file_part).resolve() if file_part else doc
        if not dest.exists():
            broken.append(f"{target}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            broken.append(f"{target}: no heading with that anchor")
    assert not broken, f"{doc.name}: " + "; ".join(broken)


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(REPO).as_posix())
def test_code_fences_are_closed(doc):
    fences = sum(1 for line in doc.read_text(encoding="utf-8").splitlines() if FENCE.match(line))
    assert fences % 2 == 0, f"{doc.name} has an odd number of ``` fences"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(REPO).as_posix())
def test_every_named_script_exists(doc):
    """A command or a sentence naming ``benchmarks/``, ``scripts/`` or ``tests/`` file must name one that exists: tests
    move into folders and benchmarks are renamed, and a plain-text path is not a link the check above would catch."""
    missing = sorted({path for path in RUNNABLE.findall(doc.read_text(encoding="utf-8")) if not (REPO / path).exists()})
    assert not missing, f"{doc.name} names missing files: {', '.join(missing)}"
