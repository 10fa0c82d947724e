"""The repros of the reliability review of 2026-11-28 (issue 45): nothing of the user's is
touched (the temp sweep, links on the way to eval and export, a hard-linked lock, eval --out),
a commit cut short is found, and values read from files give one line, not a traceback."""

from __future__ import annotations

import errno
import hashlib
import json
import logging
import os
from pathlib import Path

import numpy as np
import pytest

from imitate.cli import main
from imitate.envs import tasks
from imitate.envs.task import get_task
from imitate.errors import ImitateError
from imitate.rundir.artifacts import Staging, leftovers
from imitate.rundir.lock import LOCK, locked
from imitate.rundir.schema import check_values
from imitate.stages import provenance
from imitate.stages.config import load_config
from imitate.stages.runner import run_keys

TEMP = "{name}.4242-0123abcd.partial{suffix}"  # a killed writer's temporary name of NAME


def temp(name: str) -> str:
    return "." + TEMP.format(name=name, suffix=Path(name).suffix)


def one_error_line(err: str, command: str) -> str:
    """The only line of ``err`` besides ``== stage`` and warnings; it must be an error."""
    lines = [line for line in err.splitlines() if not line.startswith(("== ", "warning: "))]
    assert len(lines) == 1 and lines[0].startswith(f"imitate {command}: error: "), err
    return lines[0]


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# --- the sweep (N-x2, N-d2) --------------------------------------------------------------------


def _users_files(folder: Path) -> dict[Path, str]:
    (folder / "notes").mkdir(parents=True)
    files = {
        folder / ".thesis.partial.tex": "draft\n", folder / "notes" / ".todo.partial.md": "x\n",
        folder / temp("notes.txt"): "imitate's form, but no name imitate writes\n",
    }
    for path, text in files.items():
        path.write_text(text)
    return files


def test_a_folder_that_holds_no_run_is_not_swept(tmp_path, capsys):
    files = _users_files(tmp_path / "F")
    assert main(["learn", str(tmp_path / "F")]) == 1
    assert "config.json is missing" in one_error_line(capsys.readouterr().err, "learn")
    assert {p: p.read_text() for p in files} == files


def test_a_lock_file_of_the_users_is_neither_written_nor_deleted(tmp_path, capsys):
    folder = tmp_path / "F"
    folder.mkdir()
    (folder / LOCK).write_text("my notes\n")
    assert main(["learn", str(folder)]) == 1
    assert "holds no record of an imitate command" in one_error_line(
        capsys.readouterr().err, "learn"
    )
    assert (folder / LOCK).read_text() == "my notes\n"


def test_a_run_directory_reached_through_a_link_is_swept(tmp_path):
    run_dir = tmp_path / "R"
    run_dir.mkdir()
    (run_dir / "manifest.json").write_text("{}\n")
    (run_dir / temp("model.npz")).write_bytes(b"half")
    (tmp_path / "latest").symlink_to(run_dir)
    with locked(tmp_path / "latest", "imitate test"):
        pass
    assert not (run_dir / temp("model.npz")).exists()


def test_a_run_directory_is_swept_of_imitates_own_temporary_names_only(tmp_path, caplog):
    run_dir = tmp_path / "R"
    files = _users_files(run_dir)
    (run_dir / "manifest.json").write_text("{}\n")
    (run_dir / "figures").mkdir()
    (run_dir / "export" / ".hdf5.ab_c1234.partial").mkdir(parents=True)  # a killed export's
    (run_dir / "export" / ".hdf5.ab_c1234.partial" / "robot.hdf5").write_bytes(b"x")
    (run_dir / "export" / ".myds.partial").mkdir()  # a user's
    ours = [run_dir / temp("model.npz"), run_dir / temp("observation.png"),
            run_dir / "figures" / temp("gmr.png"), run_dir / temp("report.html")]
    for path in ours:
        path.write_bytes(b"half")
    assert set(leftovers(run_dir)) == {*ours, run_dir / "export" / ".hdf5.ab_c1234.partial"}
    with caplog.at_level(logging.DEBUG, "imitate"), locked(run_dir, "imitate test"):
        pass
    assert not any(p.exists() for p in ours)
    assert not (run_dir / "export" / ".hdf5.ab_c1234.partial").exists()
    assert (run_dir / "export" / ".myds.partial").is_dir()
    assert {p: p.read_text() for p in files} == files
    assert "cut short" not in caplog.text  # staged files of a stage killed before its commit


# --- the lock (N-x1) ---------------------------------------------------------------------------


def test_a_hard_linked_lock_is_refused_and_its_other_name_untouched(tmp_path, capsys):
    run_dir = tmp_path / "R"
    run_dir.mkdir()
    notes = tmp_path / "notes.txt"
    notes.write_text("notes\n")
    os.link(notes, run_dir / LOCK)
    assert main(["learn", str(run_dir)]) == 1
    line = one_error_line(capsys.readouterr().err, "learn")
    assert "is a hard link" in line and f"rm {run_dir / LOCK}" in line
    assert notes.read_text() == "notes\n" and os.stat(notes).st_nlink == 2


# --- the commit (N-d1, N-c4, D8) ---------------------------------------------------------------


def test_the_commit_makes_every_folder_before_its_first_rename(tmp_path, monkeypatch):
    old = tmp_path / "video.mp4"
    old.write_text("old")
    staging = Staging(tmp_path)
    for name in ("video.mp4", "figures/gmr.png"):
        staging.write(tmp_path / name, lambda tmp: tmp.write_text("new"))
    mkdir = Path.mkdir

    def no_inode_left(self, *args, **kwargs):
        if self.name == "figures":
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return mkdir(self, *args, **kwargs)

    monkeypatch.setattr(Path, "mkdir", no_inode_left)
    with pytest.raises(ImitateError, match="cannot make folder .*figures .*nothing was replaced"):
        staging.commit()
    assert old.read_text() == "old"
    staging.discard()


def test_a_commit_cut_short_is_reported_by_the_next_command_and_marked_out_of_date(
    run_dir, caplog
):
    """As a kill -9 after the first rename of `figures`' commit leaves it (the fault-injection
    case `commit-kill-figures` does it for real): the new video in place, the rest as before, the
    staged manifest among the temporary files."""
    manifest = json.loads((run_dir / "manifest.json").read_text())
    (run_dir / "video.mp4").write_bytes(b"the new video")
    staged = json.loads(json.dumps(manifest))
    staged["figures"]["outputs"]["video.mp4"] = _sha(run_dir / "video.mp4")
    (run_dir / temp("manifest.json")).write_text(json.dumps(staged))
    (run_dir / temp("config.json")).write_text("{}")
    with caplog.at_level(logging.WARNING, "imitate"), locked(run_dir, "imitate test"):
        pass
    assert "the commit of stage figures was cut short: video.mp4 is new" in caplog.text
    assert f"run `imitate figures {run_dir}` again" in caplog.text
    assert not leftovers(run_dir)
    later = provenance.outdated(run_dir, load_config(run_dir), provenance.load(run_dir))
    assert later == {"figures": "video.mp4 is not the file it wrote (a commit cut short, or "
                                "changed since)"}


# --- links on the way to what eval and export write (S4, S10) ----------------------------------


def test_a_link_on_the_way_to_the_export_is_refused(run_dir, tmp_path, capsys):
    outside = tmp_path / "outside"
    outside.mkdir()
    (run_dir / "export").symlink_to(outside, target_is_directory=True)
    assert main(["export", str(run_dir), "--format", "hdf5"]) == 1
    line = one_error_line(capsys.readouterr().err, "export")
    assert f"{run_dir / 'export'} is a symbolic link" in line
    assert not any(outside.iterdir())


# --- values read from files (N-e3, N-e5) -------------------------------------------------------


@pytest.mark.parametrize(("section", "change", "named"), [
    ("perception", {"pos_err_mm_median": "abc"}, "perception.pos_err_mm_median='abc'"),
    ("timings", {"learn": "abc"}, "timings.learn='abc'"),
    ("perception", None, "perception.pos_err_mm_median is missing"),
])
def test_a_report_value_of_the_wrong_kind_is_one_line(run_dir, section, change, named, capsys):
    report = json.loads((run_dir / "report.json").read_text())
    report[section] = {} if change is None else {**report[section], **change}
    (run_dir / "report.json").write_text(json.dumps(report))
    assert main(["optimize", str(run_dir)]) == 1
    line = one_error_line(capsys.readouterr().err, "optimize")
    assert named in line and "delete it to start a new report" in line


def test_a_section_an_older_imitate_wrote_is_remade_by_its_stage(run_dir):
    """A report that lacks a key its own stage now writes (an older imitate's) is no reason to
    refuse that stage: it writes the section anew (a teacher's run is remade so)."""
    report = json.loads((run_dir / "report.json").read_text())
    del report["learning"]["task_space"]
    (run_dir / "report.json").write_text(json.dumps(report))
    assert main(["optimize", str(run_dir)]) == 1  # a later stage keeps the section: refused
    assert main(["learn", str(run_dir)]) == 0
    assert "task_space" in json.loads((run_dir / "report.json").read_text())["learning"]


def test_a_long_value_makes_no_long_error_line(run_dir, tmp_path, capsys):
    """Review T10i: a 1 MB value in config.json (or on the command line) was echoed whole."""
    config = json.loads((run_dir / "config.json").read_text())
    config["task"] = "x" * 10**6
    (run_dir / "config.json").write_text(json.dumps(config))
    assert main(["replay", str(run_dir)]) == 1
    line = one_error_line(capsys.readouterr().err, "replay")
    assert "config.json" in line and "task=" in line and len(line) < 1000
    with pytest.raises(SystemExit):
        main(["run", "--task", "y" * 10**5, "--out", str(tmp_path / "new")])
    err = capsys.readouterr().err
    assert "invalid choice" in err and len(err) < 1000


def test_every_report_key_without_a_unit_has_a_kind(quick_run):
    for name in tasks.NAMES:
        keys, kinds = run_keys(get_task(name))
        assert {k for k, (unit, _) in keys.items() if unit == "-"} - {"schema"} <= set(kinds)
    path = quick_run / "report.json"
    check_values(json.loads(path.read_text()), path, *run_keys(get_task("pour")))


def test_replay_of_a_plan_of_nan_is_one_line(run_dir, capsys):
    with np.load(run_dir / "plan.npz") as npz:
        arrays = {k: np.full_like(npz[k], np.nan) if npz[k].dtype.kind == "f" else npz[k]
                  for k in npz.files}
    np.savez(run_dir / "plan.npz", **arrays)
    assert main(["replay", "--force", str(run_dir)]) == 1
    line = one_error_line(capsys.readouterr().err, "replay")
    assert "plan.npz holds NaN or inf in times" in line and "imitate optimize" in line


# --- flags (E15, E13) --------------------------------------------------------------------------


@pytest.mark.parametrize("command", ["eval", "compare"])
def test_a_negative_seed_is_refused_by_every_command(tmp_path, command, capsys):
    with pytest.raises(SystemExit) as exit_:
        main([command, str(tmp_path), "--seed", "-1"])
    assert exit_.value.code == 2
    assert "argument --seed: -1 not accepted: a whole number >= 0" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["observe", str(tmp_path / "new"), "--seed", "-1"])
    assert "seed=-1 not accepted" in capsys.readouterr().err


def test_a_collision_weight_run_refuses_is_refused_by_eval_and_compare_too(tmp_path, capsys):
    assert main(["eval", str(tmp_path), "--collision-weight", "1e300"]) == 1
    line = one_error_line(capsys.readouterr().err, "eval")
    assert "collision_weight=1e+300 not accepted: a number in 0..1e+06" in line
    assert main(["compare", str(tmp_path), "--sweep", "collision_weight=1,1e300"]) == 1
    line = one_error_line(capsys.readouterr().err, "compare")
    assert "collision_weight 1e+300 is outside 0..1e+06" in line


def test_eval_and_compare_refuse_a_model_that_does_not_follow_from_the_run(run_dir, capsys):
    """Review A: after the run's seed changed, its model is another teacher's: eval and compare
    refuse it, naming the stage to re-run, as every stage does."""
    values = json.loads((run_dir / "config.json").read_text())
    (run_dir / "config.json").write_text(json.dumps({**values, "seed": 3}))
    for command in ("eval", "compare"):
        assert main([command, str(run_dir), "--n", "1", "--teachers", "1"]) == 1
        line = one_error_line(capsys.readouterr().err, command)
        assert f"re-run `imitate observe {run_dir}`" in line and "before evaluating" in line


@pytest.mark.parametrize("fifo", ["model.npz", "suite.toml"])
def test_a_fifo_where_a_file_is_read_is_refused_not_waited_for(tmp_path, fifo):
    """Review D: reading a FIFO waits for a writer forever, holding the run's lock."""
    import subprocess
    import sys

    from imitate.demos.oracle import oracle_model
    from imitate.learning import LearningConfig
    from imitate.motion.replay import planning_task
    from imitate.rundir.artifacts import save_npz

    gaze = planning_task().gaze
    learned = oracle_model(gaze, learning=LearningConfig(k_max=4), rate=20.0)
    save_npz(tmp_path / "model.npz", {**learned.to_arrays(), "gaze": gaze})
    (tmp_path / "suite.toml").write_text("particles = 40\n")
    (tmp_path / fifo).unlink()
    os.mkfifo(tmp_path / fifo)
    done = subprocess.run(
        [sys.executable, "-m", "imitate", "eval", str(tmp_path), "--suite",
         str(tmp_path / "suite.toml"), "--n", "1", "--workers", "1"],
        capture_output=True, text=True, timeout=300, check=False,
    )
    assert done.returncode == 1
    line = one_error_line(done.stderr, "eval")
    assert f"{tmp_path / fifo} is not a regular file" in line


def test_a_config_that_is_no_object_is_refused_without_quoting_it(tmp_path):
    """Review I4: a config.json linked to another file's secret list."""
    (tmp_path / "secret.json").write_text('["TOP-SECRET-TOKEN-abcdef0123456789", 1]')
    (tmp_path / "config.json").symlink_to(tmp_path / "secret.json")
    with pytest.raises(ImitateError, match="holds a JSON list, not an object") as err:
        load_config(tmp_path)
    assert "SECRET" not in str(err.value)


def test_an_unknown_setting_is_named_within_a_line_of_reasonable_length(tmp_path):
    """Review N-e4: a config.json key of a megabyte was echoed whole."""
    from imitate.stages.config import RunConfig

    values = {**RunConfig().to_json(), "x" * 1_000_000: 1, **{f"k{i}": 0 for i in range(9)}}
    with pytest.raises(ImitateError) as error:
        RunConfig.from_json(values)
    message = str(error.value)
    assert len(message) < 2000 and "['k0', 'k1', 'k2', 'k3', 'k4'] and 5 more" in message


def test_long_values_are_cut_in_the_error_line(tmp_path):
    """Review T10i, W9, L4: a megabyte of task name, sweep or weightings was quoted whole."""
    from imitate.evaluation.compare import compare, parse_sweep
    from imitate.evaluation.suite import Suite

    long = "x" * 1_000_000
    for call in (lambda: tasks.check(long), lambda: parse_sweep(f"path_length_weight={long}"),
                 lambda: compare(tmp_path, Suite.default(), ("variance", long))):
        with pytest.raises(ImitateError) as error:
            call()
        assert len(str(error.value)) < 600 and "xxx..." in str(error.value)


def test_an_empty_sweep_is_refused_not_taken_for_none(run_dir, capsys):
    """Review W7a: ``--sweep ''`` (an unset shell variable) ran a plain comparison."""
    assert main(["compare", str(run_dir), "--sweep", "", "--n", "1"]) == 1
    assert "--sweep '' not accepted" in one_error_line(capsys.readouterr().err, "compare")
    assert not (run_dir / "compare").exists()


def test_names_a_manifest_holds_outside_the_run_are_not_opened(run_dir, monkeypatch):
    """Review X5: ``../../x`` or an absolute name among a stage's outputs was hashed."""
    outside = run_dir.parent / "users-file.bin"
    outside.write_bytes(b"private")
    manifest = json.loads((run_dir / provenance.MANIFEST).read_text())
    manifest["learn"]["outputs"]["../users-file.bin"] = "0" * 64
    manifest["learn"]["outputs"][str(outside)] = "0" * 64
    opened = []
    real = provenance.digest
    monkeypatch.setattr(provenance, "digest", lambda path: opened.append(path) or real(path))
    provenance.outdated(run_dir, load_config(run_dir), manifest)
    assert opened and all(Path(p).parent == run_dir or run_dir in Path(p).parents for p in opened)


def test_a_run_switched_to_another_task_is_told_what_to_run_again(run_dir, capsys):
    """Review T11a: with config.json switched to insert, replay advised deleting report.json
    (checked against the new task's keys before provenance named the real problem)."""
    config = json.loads((run_dir / "config.json").read_text())
    (run_dir / "config.json").write_text(json.dumps({**config, "task": "insert", "options": {}}))
    assert main(["replay", str(run_dir)]) == 1
    line = one_error_line(capsys.readouterr().err, "replay")
    assert "report.json" not in line and "imitate " in line and "--force" in line


def test_a_rerun_command_is_one_line_a_shell_reads_back(run_dir, capsys):
    """Review N-e12: a newline in the run directory's path came out as a space in the re-run
    command."""
    from imitate.errors import shell_word

    assert shell_word("runs/latest") == "runs/latest" and shell_word("my runs") == "'my runs'"
    assert shell_word("a\nb'c") == "$'a\\x0ab\\x27c'"
    odd = run_dir.parent / "a\nb"
    run_dir.rename(odd)
    (odd / "model.npz").unlink()
    assert main(["optimize", str(odd)]) == 1
    line = one_error_line(capsys.readouterr().err, "optimize")
    assert f"`imitate learn {shell_word(odd)}`" in line
