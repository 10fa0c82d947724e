"""Tasks are plug-ins: the generic packages name no task, and every task gives what they use."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from imitate.cli import main
from imitate.envs import tasks
from imitate.envs.task import get_task
from imitate.errors import ImitateError
from imitate.stages import provenance, table
from imitate.stages.config import RunConfig, load_config

ROOT = Path(__file__).resolve().parents[1]
# The packages that receive a task as a value and must not know any one task.
GENERIC = ("learning", "perception", "motion", "demos", "stages", "evaluation", "rundir",
           "figures", "export")
TASK_WORDS = re.compile(r"pour|bottle|glass|liquid|particle", re.IGNORECASE)


def task_words(root: Path = ROOT) -> list[str]:
    """``path:line: text`` of every line of the generic packages under ``root`` that names a
    task word."""
    found = []
    for name in GENERIC:
        for path in sorted((root / "imitate" / name).rglob("*")):
            if path.suffix not in (".py", ".toml") or "__pycache__" in path.parts:
                continue
            for number, line in enumerate(path.read_text().splitlines(), 1):
                if TASK_WORDS.search(line):
                    found.append(f"{path.relative_to(root)}:{number}: {line.strip()}")
    return found


def test_the_generic_packages_name_no_task():
    found = task_words()
    assert not found, f"{len(found)} lines name a task:\n" + "\n".join(found[:40])


def test_the_word_check_finds_a_task_word(tmp_path):
    """The check is not blind: a task word written into a generic package is found."""
    package = tmp_path / "imitate" / "motion"
    package.mkdir(parents=True)
    (package / "mod.py").write_text('"""Plans the Pour."""\n')
    assert task_words(tmp_path) == ['imitate/motion/mod.py:1: """Plans the Pour."""']


@pytest.mark.parametrize("name", tasks.NAMES)
def test_every_task_gives_what_the_generic_layers_use(name):
    task = get_task(name)
    assert task.name == name and task.outcomes[0] == "success"
    assert len(task.dims) == task.space.m and len(task.objects) == 2
    # The objects are written once: the teacher's script moves the env's.
    assert tasks.module(name, "teacher").SCRIPT.objects == task.objects
    assert all(f"{obj}_grasp" in task.options for obj in task.objects)
    assert sorted(p.stem for p in task.suites.glob("*.toml")), "a task ships its suites"
    scene = task.scene()
    assert scene.objects == task.objects
    assert set(task.reset_options()) == {f"{obj}_grasp" for obj in task.objects}


@pytest.mark.parametrize("name", tasks.NAMES)
def test_every_teachers_demonstrations_do_the_task_in_physics(name):
    """As Meta-World checks each expert: the first and the last of three demonstrations (seed 1)
    succeed in physics, by the teacher module's own check (``demonstrated``)."""
    from imitate.envs.teacher_motion import TeacherConfig, script_demonstrations

    motion = script_demonstrations(TeacherConfig(task=name, n_demos=3, seed=1))
    assert all(tasks.module(name, "teacher").demonstrated(motion, demo) for demo in (0, 2))


def test_a_task_is_a_folder_found_by_its_modules_not_a_list(tmp_path):
    for name, parts in (("stack", tasks.PARTS), ("pour", tasks.PARTS), ("notes", ("task",))):
        (tmp_path / name).mkdir()
        for part in ("__init__", *parts):
            (tmp_path / name / f"{part}.py").write_text("")
    assert tasks.found(tmp_path) == ("pour", "stack")  # the default first; no half a task
    assert tasks.found() == tasks.NAMES and {"pour", "insert"} <= set(tasks.NAMES)


def test_an_unknown_task_is_refused_with_the_known_ones():
    known = re.escape(f"task 'stir' unknown; accepted: {list(tasks.NAMES)}")
    with pytest.raises(ImitateError, match=known):
        get_task("stir")


def test_a_setting_of_another_task_is_refused():
    with pytest.raises(ImitateError, match="particles"):
        get_task("insert").settings({"particles": 30})



def test_a_task_setting_is_an_input_of_the_stage_that_first_uses_it(quick_run, tmp_path):
    """``--particles`` (the replay's) given to ``imitate replay`` is applied there, not refused
    as a change of the observation; a changed grasp (the optimizer's) leaves the learned model
    fresh and makes the plan stale."""
    run_dir = tmp_path / "run"
    shutil.copytree(quick_run, run_dir, ignore=shutil.ignore_patterns("*.mp4", "figures"))
    assert main(["replay", str(run_dir), "--particles", "20", "-q"]) == 0
    assert load_config(run_dir).options["particles"] == 20
    manifest = provenance.load(run_dir)
    assert "particles" not in json.dumps(manifest["observe"])
    values = json.loads((run_dir / "config.json").read_text())
    values["options"]["bottle_grasp"] = 0.1
    regrasped = RunConfig.from_json(values)
    assert not provenance.stale(run_dir, table.find("optimize"), regrasped, manifest)
    assert provenance.stale(run_dir, table.find("replay"), regrasped, manifest)
