"""The docs point only at files of the repository: a user's checkout has nothing else."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md")])
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")  # [text](target#anchor)
PATH = re.compile(r"`((?:\.\./|/)[^`\s]+\.(?:md|py|json|toml))`")  # `../x/y.md`, `/abs/file.py`


def test_every_link_in_the_docs_resolves_inside_the_repository():
    # issue 27: docs/simulators.md cited ../shared/reference/protocols.md, outside the repository
    bad = []
    for doc in DOCS:
        text = doc.read_text()
        for target in LINK.findall(text):
            if re.match(r"[a-z]+:", target):  # https:, mailto:
                continue
            path = (doc.parent / target).resolve()
            if not path.is_relative_to(ROOT) or not path.exists():
                bad.append(f"{doc.relative_to(ROOT)}: ({target})")
        for target in PATH.findall(text):
            path = (doc.parent / target).resolve()
            if not path.is_relative_to(ROOT) or not path.exists():
                bad.append(f"{doc.relative_to(ROOT)}: `{target}`")
    assert not bad, bad
