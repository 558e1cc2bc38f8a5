"""House rules that a reader sees: no line of code over 100 characters, a short README."""

from __future__ import annotations

import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LIMIT = 100


def _tracked(*patterns: str) -> list[Path]:
    out = subprocess.run(["git", "ls-files", *patterns], cwd=ROOT, capture_output=True,
                         text=True)
    if out.returncode != 0:  # not a git checkout (an sdist): look at the tree
        return [p for pat in patterns for p in ROOT.rglob(pat.lstrip("*/"))]
    return [ROOT / line for line in out.stdout.splitlines() if line]


def test_no_line_over_100_characters():
    files = _tracked("*.py", "pyproject.toml", ".ci/run")
    assert any(p.name == "driver.py" for p in files)
    long = [f"{p.relative_to(ROOT)}:{i}" for p in files if p.is_file()
            for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
            if len(line) > LIMIT]
    assert long == []


def test_readme_is_a_guide():
    """The README is the short guide (issue 32); the reference lives in docs/."""
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 250
