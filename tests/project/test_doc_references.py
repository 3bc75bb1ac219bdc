"""Every document the repository cites is in the repository: a user's clone has no design notes
beside it, so a citation of ``stl-funnel.md §9`` must find ``docs/stl-funnel.md``, and nothing
may point outside the clone (``../shared``, ``shared/design``)."""

from __future__ import annotations

import os
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SKIP_DIRS = {".git", ".venv", "build", "results", "__pycache__", "tlfleet.egg-info",
             ".pytest_cache", ".ruff_cache", ".hypothesis", "runs", "dist"}
SUFFIXES = {".py", ".md", ".toml", ".yaml", ".yml", ".sh", ".c", ".h", ".json5", ".txt", ".cfg"}
#: names that are a run's output or the repository's own root files, not documents to read here
NOT_DOCUMENTS = {"report.md"}
CITATION = re.compile(r"(?<![\w/.-])((?:\.\./)*[\w./-]*?[\w-]+\.md)\b")
OUTSIDE = re.compile(r"\.\./shared|shared/design")


def text_files() -> list[Path]:
    """The repository's text files (this test's own aside: it spells the patterns out)."""
    out = []
    for folder, dirs, files in os.walk(ROOT):
        dirs[:] = [d for d in dirs if d not in SKIP_DIRS]
        for name in files:
            path = Path(folder) / name
            if (path.suffix in SUFFIXES or name == "Makefile") and path != Path(__file__):
                out.append(path)
    return out


def resolves(name: str, citing: Path) -> bool:
    base = Path(name).name
    return (base in NOT_DOCUMENTS or (citing.parent / name).is_file()
            or (ROOT / name).is_file() or (ROOT / "docs" / base).is_file()
            or (ROOT / base).is_file())


def test_no_file_cites_a_document_the_clone_lacks():
    missing, outside = [], []
    for path in text_files():
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        rel = path.relative_to(ROOT).as_posix()
        for number, line in enumerate(text.splitlines(), start=1):
            if OUTSIDE.search(line):
                outside.append(f"{rel}:{number}: {line.strip()[:100]}")
            for name in CITATION.findall(line):
                if not resolves(name, path):
                    missing.append(f"{rel}:{number}: {name}")
    assert outside == [], "\n".join(outside)
    assert missing == [], "\n".join(missing[:40])


def test_the_check_catches_a_missing_page(tmp_path):
    """The citation pattern finds what the test exists for (a wrong implementation that matched
    nothing would pass the test above)."""
    line = "per stl-funnel.md §9 and ltl-planning.md §5, see ../shared/design/x.md"
    assert CITATION.findall(line) == ["stl-funnel.md", "ltl-planning.md",
                                      "../shared/design/x.md"]
    assert not resolves("no-such-page.md", tmp_path / "x.py")
    assert resolves("stl-funnel.md", tmp_path / "x.py")
    assert OUTSIDE.search(line)
