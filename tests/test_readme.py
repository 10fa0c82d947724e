"""The README stays a user's manual: short, no notebook residue, no dangling links."""

import os
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


# --- The README's Python blocks, run as written where `make run` leaves the user ---------------

MAKEFILE = ROOT / "Makefile"
PYPROJECT = ROOT / "pyproject.toml"
BLOCK = re.compile(r"^```python\n(.*?)^```", re.MULTILINE | re.DOTALL)
# Imported at start-up of every Python process in the test's environment: a module of a package
# `make run` does not install raises ModuleNotFoundError, as it would there.
BLOCKER = '''import importlib.abc
import sys

ABSENT = {absent!r}


class _NotInstalledByMakeRun(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in ABSENT:
            raise ModuleNotFoundError(f"No module named {{name!r}} (make run does not install it)",
                                      name=name)
        return None


sys.meta_path.insert(0, _NotInstalledByMakeRun())
'''


def make_run_requirements() -> list[str]:
    """What `make run` installs: the package with the extras of the Makefile's
    ``$(BIN)/.installed`` target, as requirement strings (pyproject.toml's, unresolved)."""
    target = re.search(r"^\$\(BIN\)/\.installed:.*?\n\t\$\(call install,([^)]*)\)",
                       MAKEFILE.read_text(), re.MULTILINE | re.DOTALL)
    assert target, "Makefile: no $(BIN)/.installed target that calls install"
    text = PYPROJECT.read_text()
    lists = ["dependencies"] + re.findall(r"[\w-]+", target[1])
    found = []
    for name in lists:
        block = re.search(rf"^{re.escape(name)} = \[(.*?)^\]", text, re.MULTILINE | re.DOTALL)
        assert block, f"pyproject.toml: no list {name!r}"
        found += re.findall(r'^\s*"([^"]+)"', block[1], re.MULTILINE)
    return found


def installed_closure(requirements: list[str]) -> set[str]:
    """The installed distributions (normalized names) these requirements pull in."""
    from importlib import metadata

    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    seen: set[str] = set()
    todo = [Requirement(r) for r in requirements]
    while todo:
        req = todo.pop()
        name = canonicalize_name(req.name)
        if name in seen:
            continue
        try:
            dist = metadata.distribution(req.name)
        except metadata.PackageNotFoundError:
            continue  # a requirement of another platform or Python
        seen.add(name)
        extras = [""] + sorted(req.extras)
        for line in dist.requires or []:
            sub = Requirement(line)
            if sub.marker is None or any(sub.marker.evaluate({"extra": e}) for e in extras):
                todo.append(sub)
    return seen


def absent_after_make_run() -> set[str]:
    """Top-level modules installed here that `make run` does not install (test-only
    packages and their dependencies)."""
    from importlib import metadata

    from packaging.utils import canonicalize_name

    kept = installed_closure(make_run_requirements())
    return {
        module for module, dists in metadata.packages_distributions().items()
        if module != "imitate" and not any(canonicalize_name(d) in kept for d in dists)
    }


def test_the_absent_modules_are_the_test_only_ones():
    absent = absent_after_make_run()
    assert {"pytest", "sklearn", "hypothesis"} <= absent
    assert not {"numpy", "mujoco", "gymnasium", "scipy", "minari", "h5py"} & absent


def test_readme_python_blocks_run_as_written_after_make_run(quick_run, tmp_path):
    """Every ```python block of the README, each as a script in a folder whose runs/latest is
    a quick run, with only what `make run` installs importable."""
    import subprocess
    import sys

    blocks = BLOCK.findall(README.read_text(encoding="utf-8"))
    assert len(blocks) >= 2
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "latest").symlink_to(quick_run)
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(BLOCKER.format(absent=sorted(absent_after_make_run())))
    env = {k: v for k, v in os.environ.items() if k != "MINARI_DATASETS_PATH"}
    env["PYTHONPATH"] = str(site)
    printed = []
    for n, block in enumerate(blocks, start=1):
        script = tmp_path / f"readme_block{n}.py"
        script.write_text(block)
        result = subprocess.run([sys.executable, script.name], cwd=tmp_path, env=env,
                                capture_output=True, text=True, check=False, timeout=600)
        assert result.returncode == 0, f"README's Python block {n}:\n{result.stderr[-3000:]}"
        printed.append(result.stdout)
    out = "".join(printed)
    assert re.search(r"dz varies by 2 sigma = \d+ to \d+ mm", out), out
    assert re.search(r"clearance -?\d+\.\d mm, pour \d\.\d\d", out), out
