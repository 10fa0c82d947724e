"""Every script under ``scripts/`` imports (by path, its main not run), and each member it reads
from a module of the package (``tracks.name``, ``imitate.stages.figures.name``) exists: a rename
in the package breaks this test, not the script's next run."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted((ROOT / "scripts").rglob("*.py"))


def load(path: Path) -> ModuleType:
    """The script at ``path``, imported under a name of its own (so not as ``__main__``; in
    ``sys.modules`` while it runs, as its dataclasses need)."""
    name = "script_" + "_".join(path.relative_to(ROOT / "scripts").with_suffix("").parts)
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = sys.modules[name] = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    finally:
        del sys.modules[name]
    return module


def imported(tree: ast.AST) -> dict[str, object]:
    """The package's objects that the script's imports bind, by name, where an import is the
    only thing that binds that name in the file."""
    bound: dict[str, list[object]] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "imitate":
                    module = importlib.import_module(alias.name)
                    name = alias.asname or "imitate"
                    bound.setdefault(name, []).append(
                        module if alias.asname else importlib.import_module("imitate"))
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "imitate":
            assert node.module is not None
            for alias in node.names:
                try:
                    value = importlib.import_module(f"{node.module}.{alias.name}")
                except ModuleNotFoundError:
                    value = getattr(importlib.import_module(node.module), alias.name)
                bound.setdefault(alias.asname or alias.name, []).append(value)
        elif isinstance(node, ast.Name) and not isinstance(node.ctx, ast.Load):
            bound.setdefault(node.id, []).append(None)
        elif isinstance(node, ast.arg):
            bound.setdefault(node.arg, []).append(None)
    return {name: values[0] for name, values in bound.items()
            if None not in values and all(value is values[0] for value in values)}


def missing(tree: ast.AST) -> list[str]:
    """Each ``module.member`` the script reads from a module of the package that lacks it."""
    objects, wrong = imported(tree), []
    for node in ast.walk(tree):
        chain, root = [], node
        while isinstance(root, ast.Attribute):
            chain.insert(0, root.attr)
            root = root.value
        if not (chain and isinstance(root, ast.Name) and root.id in objects):
            continue
        value = objects[root.id]
        for depth, member in enumerate(chain):
            if not isinstance(value, ModuleType):
                break
            if not hasattr(value, member):
                wrong.append(".".join([value.__name__, *chain[depth:depth + 1]]))
                break
            value = getattr(value, member)
    return sorted(set(wrong))


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda path: str(path.relative_to(ROOT)))
def test_a_script_imports_and_finds_what_it_reads(path):
    load(path)
    assert missing(ast.parse(path.read_text(), str(path))) == []


def test_a_missing_member_is_seen():
    tree = ast.parse(
        "from imitate import errors\nimport imitate.rundir.lock\n"
        "def f():\n    errors.ImitateError, errors.nothing_here\n"
        "    imitate.rundir.lock.also_not_here\n"
    )
    assert missing(tree) == ["imitate.errors.nothing_here", "imitate.rundir.lock.also_not_here"]


def test_paired_evals_pairs_two_weightings_of_a_comparison(tmp_path, capsys):
    """Two weightings of one comparison, paired per teacher: success and a watched number as
    written, a line an interruption cut skipped; a weighting not compared, and records that are
    not the ones compare.json counts, are refused."""
    paired = load(ROOT / "scripts" / "experiments" / "paired_evals.py")
    lines = []
    for teacher in (0, 1, 2):
        for i in range(2):
            for weighting, ok in (("variance", i == 0), ("precision", True)):
                lines.append(json.dumps({
                    "teacher": teacher, "id": i, "outcome": "success" if ok else "spill",
                    "settings": {"id": i, "similarity": weighting}, "pour_mean": 1.0 if ok else 0.5,
                    "replays": [{"geometry": {"offset_m": 0.01 if ok else 0.05, "seen": None}}]}))
    (tmp_path / "results.jsonl").write_text("\n".join(lines) + '\n{"teacher": 0, "id"')
    (tmp_path / "compare.json").write_text(json.dumps({
        "task": "pour", "teachers": [0, 1, 2], "variations_per_teacher": 2,
        "weightings": {w: {"by_teacher": {str(t): {"success": n} for t in (0, 1, 2)}}
                       for w, n in (("variance", 1), ("precision", 2))}}))
    assert paired.main([f"{tmp_path}:variance", f"{tmp_path}:precision"]) == 0
    out = capsys.readouterr().out
    assert "| 1 | 1/2 | 2/2 |" in out
    assert "success: -50 pp [no spread], 0 / 3 / 0" in out
    assert "offset_m: +0.02 [no spread], 3 / 0 / 0" in out and "seen" not in out
    with pytest.raises(SystemExit):
        paired.main([f"{tmp_path}:variance", f"{tmp_path}:uniform"])
    assert "compared variance, precision, not uniform" in capsys.readouterr().err
    with (tmp_path / "results.jsonl").open("a") as results:  # a later comparison's record
        results.write("\n" + lines[0].replace('"success"', '"spill"'))
    with pytest.raises(SystemExit):
        paired.main([f"{tmp_path}:variance", f"{tmp_path}:precision"])
    assert "does not hold the successes its compare.json counts" in capsys.readouterr().err
