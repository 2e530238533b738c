"""The documentation a newcomer reads resolves: every ``docs/physics.md §…`` / ``docs/tasks.md §…`` reference in the
repository names a section that exists, every relative link and image in the top-level docs points at a file,
and every ``BENCHMARKS.md#anchor`` link names a heading of BENCHMARKS.md."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ("README.md", "BENCHMARKS.md", "docs/architecture.md", "docs/conventions.md", "docs/physics.md",
        "docs/tasks.md")

REF = re.compile(r"docs/(physics|tasks)\.md\s*§\s*(\d+)(?:\.(\d+))?(?: ?([A-G])(?:\.\d+)?)?")
OPEN_POINT = re.compile(r"docs/tasks\.md\s+(O\d+)")


def _sections(name: str) -> set[str]:
    """Section ids of docs/<name>.md: '2', '2.3', and lettered sub-sections of a numbered section ('8A')."""
    out: set[str] = set()
    current = ""
    for line in (ROOT / "docs" / f"{name}.md").read_text(encoding="utf-8").splitlines():
        m = re.match(r"^(#{2,3}) (\d+)(?:\.(\d+))?[. ]", line)
        if m:
            current = m.group(2)
            out.add(current if m.group(3) is None else f"{current}.{m.group(3)}")
            continue
        m = re.match(r"^### ([A-Z])\. ", line)
        if m and current:
            out.add(current + m.group(1))
    return out


def _tracked_text_files() -> list[Path]:
    names = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    keep = (".py", ".md", ".toml")
    return [ROOT / n for n in names if n.endswith(keep) and (ROOT / n).is_file()]


def test_section_references_resolve():
    sections = {"physics": _sections("physics"), "tasks": _sections("tasks")}
    assert {"1.1", "1.6", "4.7", "8", "8A", "8E"} <= sections["physics"]
    assert {"2.4", "3.3", "7.2", "8.1"} <= sections["tasks"]
    dangling = []
    count = 0
    for path in _tracked_text_files():
        text = path.read_text(encoding="utf-8", errors="replace")
        for m in REF.finditer(text):
            count += 1
            doc, major, minor, letter = m.groups()
            sid = major + (f".{minor}" if minor else "") + (letter or "")
            if sid not in sections[doc]:
                dangling.append(f"{path.relative_to(ROOT)}: {m.group(0)!r}")
        tasks_text = (ROOT / "docs" / "tasks.md").read_text(encoding="utf-8")
        for m in OPEN_POINT.finditer(text):
            count += 1
            if f"**{m.group(1)} " not in tasks_text:
                dangling.append(f"{path.relative_to(ROOT)}: {m.group(0)!r}")
    assert count > 50, "the reference pattern no longer matches the code's references"
    assert not dangling, "references to missing sections:\n" + "\n".join(dangling)


def test_no_references_to_files_outside_the_repository():
    bad = []
    for path in _tracked_text_files():
        if path.parent == ROOT / "docs":
            continue  # pages in docs/ name their siblings relatively (checked by test_links_and_images_resolve)
        text = path.read_text(encoding="utf-8", errors="replace")
        for m in re.finditer(r"(?<![\w/.])(physics|tasks)\.md\s*§", text):
            bad.append(f"{path.relative_to(ROOT)}: {text[max(0, m.start() - 30):m.end() + 10]!r}")
    assert not bad, "bare physics.md / tasks.md references (use docs/physics.md, docs/tasks.md):\n" + "\n".join(bad)


def _anchor(heading: str) -> str:
    """GitHub's anchor of a markdown heading."""
    s = heading.strip().lower()
    s = re.sub(r"[^\w\- ]", "", s)
    return s.replace(" ", "-")


@pytest.mark.parametrize("doc", DOCS)
def test_links_and_images_resolve(doc):
    path = ROOT / doc
    text = path.read_text(encoding="utf-8")
    missing = []
    for m in re.finditer(r"!?\[[^\]]*\]\(([^)\s]+)\)", text):
        target = m.group(1)
        if re.match(r"^[a-z]+://|^mailto:", target):
            continue
        file_part, _, anchor = target.partition("#")
        dest = path if not file_part else (path.parent / file_part)
        if not dest.exists():
            missing.append(target)
            continue
        if anchor and dest.suffix == ".md":
            heads = {_anchor(h) for h in re.findall(r"^#{1,6} (.+)$", dest.read_text(encoding="utf-8"), re.M)}
            if anchor not in heads:
                missing.append(target)
    assert not missing, f"{doc}: dangling links {missing}"


def test_architecture_lists_every_sim_module():
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    missing = [p.name for p in sorted((ROOT / "sim").glob("*.py")) if p.name not in text]
    assert not missing, f"docs/architecture.md does not list sim modules {missing}"
