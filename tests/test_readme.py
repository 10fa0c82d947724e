"""The README stays a user's manual: short, no notebook residue, no dangling links."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
MAX_LINES = 300

# A commit-hash-like token: 7-40 hex digits with at least one digit and one letter.
HEX = re.compile(r"\b(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b", re.IGNORECASE)
DATE = re.compile(r"\b\d{4}-\d{2}-\d{2}\b")
ISSUE = re.compile(r"\bissues?\s+#?\d+|(?<![\w&])#\d+\b", re.IGNORECASE)
LINK = re.compile(r"\]\(([^)\s]+)")


def lines() -> list[str]:
    return README.read_text(encoding="utf-8").splitlines()


def offending(pattern: re.Pattern) -> list[str]:
    return [
        f"README.md:{n}: {m.group(0)!r} in {line.strip()!r}"
        for n, line in enumerate(lines(), start=1)
        for m in pattern.finditer(line)
    ]


def test_readme_is_at_most_300_lines():
    count = len(lines())
    assert count <= MAX_LINES, (
        f"README.md has {count} lines, at most {MAX_LINES}: move measurements to "
        "scripts/README.md and reference tables to the code's --help"
    )


def test_readme_has_no_hashes():
    found = offending(HEX)
    assert not found, "commit hashes or digests in README.md:\n" + "\n".join(found)


def test_readme_has_no_dates():
    found = offending(DATE)
    assert not found, "dates in README.md:\n" + "\n".join(found)


def test_readme_has_no_issue_references():
    found = offending(ISSUE)
    assert not found, "issue references in README.md:\n" + "\n".join(found)


def test_readme_says_how_to_activate_the_venv():
    assert re.search(r"\bactivate\b", README.read_text(encoding="utf-8")), (
        "README.md must say how to activate the venv (source .venv/bin/activate)"
    )


def test_readme_relative_links_exist():
    missing = []
    for n, line in enumerate(lines(), start=1):
        for m in LINK.finditer(line):
            target = m.group(1)
            if target.startswith(("http://", "https://", "mailto:", "#")):
                continue
            path = target.split("#", 1)[0]
            if path and not (ROOT / path).exists():
                missing.append(f"README.md:{n}: {target}")
    assert not missing, "links to files that do not exist:\n" + "\n".join(missing)
