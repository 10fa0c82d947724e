"""The package's layers: each module imports only from the layers below its own (and from its own
package), with no import cycle; every import counts, in a function or under ``TYPE_CHECKING``
alike, and so does a module named by string (``import_module("...")``, ``"pkg.mod:fn"``). The
README's Architecture section draws the same map."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# Source folders of the package (envs/ and models/ install as imitate.envs and imitate.models).
SOURCES = {
    "imitate": ROOT / "imitate", "imitate.envs": ROOT / "envs", "imitate.models": ROOT / "models",
}
# Bottom first. Within a layer a module imports only from its own package, except in the
# first, whose modules are one package of helpers.
LAYERS = (
    ("imitate.errors", "imitate._validation", "imitate._numba", "imitate.defaults",
     "imitate.models", "imitate.taskspace"),
    ("imitate.rundir",),
    ("imitate.envs",),
    ("imitate.learning", "imitate.perception"),
    ("imitate.motion",),
    ("imitate.demos", "imitate.figures"),
    ("imitate.stages",),
    ("imitate.run",),
    ("imitate.evaluation",),
    ("imitate.export",),
    ("imitate.warmup",),
    ("imitate.cli",),
    ("imitate.__main__",),
)
# The package's root: the facade (ENV_ID, ImitateError, load_run imported on first use), which
# every layer may import and which may import every layer.
FACADE = "imitate"
# A string that names a module's member, as an entry point does: "imitate.cli:main".
ENTRY_POINT = re.compile(r"(imitate(?:\.\w+)*):\w+(?:\.\w+)*")
# The imports by string that stand for now, as (module, package of what it names): the stage
# table names each stage's function ("imitate.stages.<stage>:run"), and the stages' files read
# the table back for their re-run hints, a cycle. Delete the entry once the table names none.
STANDING = {("imitate.stages.table", "imitate.stages")}


def modules() -> dict[str, Path]:
    """Every module of the package by dotted name."""
    found = {}
    for package, folder in SOURCES.items():
        for path in folder.rglob("*.py"):
            if "__pycache__" in path.parts or (package == "imitate" and path.parts[
                len(folder.parts)
            ] in ("envs", "models")):
                continue
            parts = path.relative_to(folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join((package, *parts))] = path
    return found


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The package's modules that ``name`` imports anywhere in its file (``from p import m``
    with ``m`` a module counts as ``p.m``)."""
    tree = ast.parse(path.read_text(), str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1]
                                + ([base] if base else []))
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base
                       for alias in node.names]
        else:
            continue
        found |= resolved(targets, name, known)
    return found


def named(name: str, path: Path, known: set[str]) -> set[str]:
    """The package's modules that ``name`` names by string to import them: the argument of
    ``import_module(...)`` or ``__import__(...)`` (of an f-string, its constant head up to the
    last dot), and every ``"pkg.mod:fn"`` string (an entry point)."""
    targets = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            match = ENTRY_POINT.fullmatch(node.value)
            targets += [match[1]] if match else []
        elif isinstance(node, ast.Call) and node.args and (
            getattr(node.func, "id", None) in ("import_module", "__import__")
            or getattr(node.func, "attr", None) == "import_module"
        ):
            argument = node.args[0]
            if isinstance(argument, ast.JoinedStr):
                head = argument.values[0] if argument.values else None
                if isinstance(head, ast.Constant) and "." in head.value:
                    targets.append(head.value.rpartition(".")[0])
            elif isinstance(argument, ast.Constant) and isinstance(argument.value, str):
                targets.append(argument.value)
    return resolved(targets, name, known)


def resolved(targets: list[str], name: str, known: set[str]) -> set[str]:
    """The package's modules that hold ``targets`` (dotted names), ``name`` itself aside."""
    found = set()
    for target in targets:
        module = target
        while module and module not in known:
            module = module.rpartition(".")[0]
        if module and module != name:
            found.add(module)
    return found


def standing(name: str, targets: set[str]) -> set[str]:
    """Those of ``name``'s imports by string that :data:`STANDING` lets stand."""
    return {target for target in targets for module, package in STANDING
            if name == module and (target == package or target.startswith(package + "."))}


def layer(name: str) -> tuple[int, str]:
    """``name``'s layer (its index in LAYERS) and its package there."""
    for index, packages in enumerate(LAYERS):
        for package in packages:
            if name == package or name.startswith(package + "."):
                return index, "imitate" if index == 0 else package
    raise AssertionError(f"{name} is in no layer: add it to LAYERS (and to the README's map)")


def upward(graph: dict[str, set[str]]) -> list[str]:
    """Each import that goes up a layer or sideways into another package of its layer."""
    wrong = []
    for name, targets in sorted(graph.items()):
        if name == FACADE:
            continue
        here, package = layer(name)
        for target in sorted(targets - {FACADE}):
            there, other = layer(target)
            if there > here or (there == here and other != package):
                wrong.append(f"{name} (layer {here}) imports {target} (layer {there})")
    return wrong


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import cycles among the modules (not through the facade), each as a path."""
    found, state = [], {}

    def visit(name: str, path: list[str]) -> None:
        state[name] = "open"
        for target in sorted(graph.get(name, set()) - {FACADE}):
            if state.get(target) == "open":
                found.append(path[path.index(target):] + [target])
            elif target not in state:
                visit(target, path + [target])
        state[name] = "done"

    for name in sorted(graph):
        if name not in state and name != FACADE:
            visit(name, [name])
    return found


@pytest.fixture(scope="module")
def strings() -> dict[str, set[str]]:
    """Each module's imports by string."""
    found = modules()
    return {name: named(name, path, set(found)) for name, path in found.items()}


@pytest.fixture(scope="module")
def graph(strings) -> dict[str, set[str]]:
    found = modules()
    return {
        name: imports(name, path, set(found)) | strings[name] - standing(name, strings[name])
        for name, path in found.items()
    }


def test_every_module_has_a_layer(graph):
    for name in graph:
        if name != FACADE:
            layer(name)


def test_no_module_imports_upward(graph):
    assert upward(graph) == []


def test_no_import_cycle(graph):
    assert cycles(graph) == []


def test_the_check_sees_an_upward_import_and_a_cycle():
    graph = {
        "imitate.learning.gmm": {"imitate.motion.plan", "imitate.errors"},
        "imitate.motion.plan": {"imitate.learning.gmm"},
        "imitate.stages.config": {"imitate.cli"},
    }
    assert upward(graph) == [
        "imitate.learning.gmm (layer 3) imports imitate.motion.plan (layer 4)",
        "imitate.stages.config (layer 6) imports imitate.cli (layer 11)",
    ]
    cycle = ["imitate.learning.gmm", "imitate.motion.plan", "imitate.learning.gmm"]
    assert cycles(graph) == [cycle]


def test_a_type_checking_import_counts(tmp_path):
    source = tmp_path / "m.py"
    source.write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from imitate.cli import main\n"
        "def f():\n    from imitate.motion import plan\n"
    )
    known = {"imitate.cli", "imitate.motion", "imitate.motion.plan"}
    assert imports("imitate.learning.m", source, known) == {"imitate.cli", "imitate.motion.plan"}


def test_an_import_by_string_counts(tmp_path):
    source = tmp_path / "m.py"
    source.write_text(
        "import importlib\nfrom importlib import import_module\n"
        "BODY = 'imitate.stages.observe:run'\nNOTE = 'imitate.cli is not an import'\n"
        "def f(kind):\n    importlib.import_module('imitate.motion.plan')\n"
        "    import_module(f'imitate.export.to_{kind}')\n    __import__('imitate.run')\n"
    )
    known = {"imitate.cli", "imitate.export", "imitate.motion", "imitate.motion.plan",
             "imitate.run", "imitate.stages", "imitate.stages.observe"}
    assert named("imitate.learning.m", source, known) == {
        "imitate.stages.observe", "imitate.motion.plan", "imitate.export", "imitate.run",
    }


def test_each_standing_import_by_string_is_still_there(strings):
    for module, package in STANDING:
        assert standing(module, strings.get(module, set())), (
            f"{module} names nothing of {package} by string any more: delete it from STANDING"
        )


def test_the_readme_draws_the_same_map():
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## Architecture"):]
    rows = re.findall(r"^\| (\d+) [^|]*\| (.*) \|$", section, re.MULTILINE)
    drawn = [tuple(re.findall(r"`(imitate\.[a-z_]+)`", row)) for _, row in rows]
    assert drawn == list(LAYERS[:-1])  # the entry point __main__ aside
