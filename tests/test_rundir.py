"""The run directory keeps one consistent run: one command at a time, stages that refuse stale
inputs, stages that change nothing unless they succeed, and one-line errors.

The numbers in the test names are those of issue 14 (the reliability review of 2026-11-23).
"""

import contextlib
import errno
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from imitate.cli import main
from imitate.errors import ImitateError
from imitate.figures import drawing
from imitate.rundir.lock import LOCK, locked
from imitate.stages import provenance, table
from imitate.stages.config import load_config


def snapshot(directory):
    """sha256 of every file under ``directory`` (hidden ones too) by relative path."""
    return {
        p.relative_to(directory).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(directory.rglob("*"))
        if p.is_file()
    }


def one_error_line(err: str, command: str) -> str:
    """The only line of ``err`` besides ``== stage`` and warnings; it must be an error."""
    lines = [
        line for line in err.splitlines() if not line.startswith(("== ", "warning: "))
    ]
    assert len(lines) == 1 and lines[0].startswith(f"imitate {command}: error: "), err
    return lines[0]


def test_the_quick_run_is_recorded_consistently(quick_run):
    manifest = provenance.load(quick_run)
    assert list(manifest) == list(table.NAMES)
    assert manifest["learn"]["inputs"]["demos.npz"] == manifest["observe"]["outputs"]["demos.npz"]
    for name, digest in manifest["figures"]["outputs"].items():
        assert provenance.digest(quick_run / name) == digest, name
    config = load_config(quick_run)
    assert provenance.stale(quick_run, table.find("figures"), config, manifest) == []
    assert not (quick_run / LOCK).exists()


# --- 1: two processes in one run directory ------------------------------------------------------


def test_1_second_command_is_refused_at_once_naming_the_holder(run_dir):
    before = snapshot(run_dir)
    with locked(run_dir, "imitate figures (the test)"):
        done = subprocess.run(
            [sys.executable, "-m", "imitate", "figures", str(run_dir)],
            capture_output=True, text=True, timeout=120, check=False,
        )
    assert done.returncode == 1
    line = one_error_line(done.stderr, "figures")
    assert f"in use by pid {os.getpid()}" in line and "imitate figures (the test)" in line
    assert snapshot(run_dir) == before


def test_1_lock_of_a_killed_process_is_no_obstacle(run_dir):
    (run_dir / LOCK).write_text(json.dumps({"pid": 2**22 + 1, "host": "h", "command": "x",
                                            "since": "then"}))
    with locked(run_dir, "imitate replay"):
        assert json.loads((run_dir / LOCK).read_text())["pid"] == os.getpid()
    assert not (run_dir / LOCK).exists()


def test_1_writers_of_one_file_do_not_share_a_temporary_name(tmp_path):
    from imitate.rundir.artifacts import load_json, save_json, write_atomic

    path = tmp_path / "report.json"

    def outer(tmp):
        tmp.write_text(json.dumps({"writer": "outer"}))
        save_json(path, {"writer": "inner"})  # another writer, before this one renames

    write_atomic(path, outer)
    assert load_json(path) == {"writer": "outer"}
    assert [p.name for p in tmp_path.iterdir()] == ["report.json"]


# --- 3: stale artifacts ---------------------------------------------------------------------


def test_3_figures_refuse_observations_newer_than_the_model(run_dir, capsys):
    assert main(["observe", "--quick", "--seed", "3", str(run_dir)]) == 0
    capsys.readouterr()
    before = snapshot(run_dir)
    assert main(["figures", str(run_dir)]) == 1
    line = one_error_line(capsys.readouterr().err, "figures")
    assert "model.npz" in line and f"imitate learn {run_dir}" in line and "--force" in line
    assert snapshot(run_dir) == before


def test_3_model_of_another_run_is_refused_unless_forced(run_dir, capsys):
    arrays = dict(np.load(run_dir / "model.npz"))
    arrays["mean"] = arrays["mean"] + 0.01  # another run's model
    np.savez(run_dir / "model.npz", **arrays)
    before = snapshot(run_dir)
    assert main(["optimize", str(run_dir), "--max-iter", "2"]) == 1
    line = one_error_line(capsys.readouterr().err, "optimize")
    assert "model.npz is not the file `imitate learn` wrote" in line
    assert snapshot(run_dir) == before
    assert main(["optimize", str(run_dir), "--max-iter", "2", "--force"]) == 0
    assert "warning: model.npz is not the file" in capsys.readouterr().err


def test_3_replay_with_another_seed_does_not_rewrite_the_runs_seed(run_dir, capsys):
    before = snapshot(run_dir)
    assert main(["replay", str(run_dir), "--seed", "5"]) == 1
    line = one_error_line(capsys.readouterr().err, "replay")
    assert "made with seed=0, not 5" in line and "imitate observe" in line
    assert snapshot(run_dir) == before


# --- 4: a failed stage changes nothing ------------------------------------------------------


@pytest.mark.parametrize("force", [[], ["--force"]])
def test_4_failed_optimize_keeps_config_and_plan(run_dir, force, capsys):
    (run_dir / "model.npz").write_bytes(b"")
    before = snapshot(run_dir)
    assert main(["optimize", str(run_dir), "--collision-weight", "30", *force]) == 1
    one_error_line(capsys.readouterr().err, "optimize")
    assert snapshot(run_dir) == before


def test_4_corrupt_report_is_found_before_the_stage_runs(run_dir, capsys):
    (run_dir / "report.json").write_text("garbage{")
    before = snapshot(run_dir)
    assert main(["replay", str(run_dir), "--particles", "10"]) == 1
    line = one_error_line(capsys.readouterr().err, "replay")
    assert "report.json is corrupt" in line and "delete it" in line
    assert snapshot(run_dir) == before


def test_4_stage_failing_after_it_wrote_leaves_nothing(run_dir, monkeypatch, capsys):
    from imitate.stages import figures

    def fails(*args, **kwargs):
        raise ImitateError("the encoder broke")

    monkeypatch.setattr(figures, "write_video", fails)  # after the seven figures
    before = snapshot(run_dir)
    assert main(["figures", str(run_dir)]) == 1
    assert "the encoder broke" in one_error_line(capsys.readouterr().err, "figures")
    assert snapshot(run_dir) == before


# --- 6: one-line errors, not tracebacks -----------------------------------------------------


@pytest.mark.parametrize(
    ("key", "value"),
    [("collision_weight", "abc"), ("n_demos", "5"), ("sweep", ["x"]), ("oracle", 1),
     ("obstacle", 5), ("options", {"particles": 2.5}), ("task", "stir")],
)
def test_6_config_of_the_wrong_type_names_file_and_key(run_dir, key, value, capsys):
    config = json.loads((run_dir / "config.json").read_text())
    (run_dir / "config.json").write_text(json.dumps({**config, key: value}))
    before = snapshot(run_dir)
    assert main(["optimize", str(run_dir)]) == 1
    line = one_error_line(capsys.readouterr().err, "optimize")
    named = next(iter(value)) if key == "options" else key  # a task's setting by its own name
    assert "config.json" in line and f"{named}=" in line
    assert snapshot(run_dir) == before


@pytest.mark.parametrize("text", ["[]", '{"timings": 5}', '{"replay": []}'])
def test_6_report_of_the_wrong_shape(run_dir, text, capsys):
    (run_dir / "report.json").write_text(text)
    assert main(["optimize", str(run_dir), "--max-iter", "2"]) == 1
    assert "report.json is not a report" in one_error_line(capsys.readouterr().err, "optimize")


def test_6_observations_lacking_an_array(run_dir, capsys):
    arrays = dict(np.load(run_dir / "observations.npz"))
    del arrays["gap_span"]
    np.savez(run_dir / "observations.npz", **arrays)
    assert main(["figures", str(run_dir)]) == 1
    line = one_error_line(capsys.readouterr().err, "figures")
    assert "observations.npz is not the file `imitate observe` wrote" in line
    assert main(["figures", str(run_dir), "--force"]) == 1
    line = one_error_line(capsys.readouterr().err, "figures")
    assert "observations.npz lacks ['gap_span']" in line and "imitate observe" in line


@pytest.mark.parametrize("command", [["observe", "--quick"], ["replay"], ["run", "--quick"]])
def test_6_run_directory_that_is_a_file(tmp_path, command, capsys):
    path = tmp_path / "run"
    path.write_text("not a run")
    assert main([*command, str(path)]) == 1
    assert "is not a directory" in one_error_line(capsys.readouterr().err, command[0])
    assert path.read_text() == "not a run"


def test_6_run_directory_under_an_unwritable_parent(capsys):
    assert main(["run", "--quick", "--out", "/proc/nope/run"]) == 1
    line = one_error_line(capsys.readouterr().err, "run")
    assert "cannot create run directory /proc/nope/run" in line


@contextlib.contextmanager
def read_only(path):
    """``path`` made unwritable (even for root: ``chattr +i``), for the block."""
    if os.geteuid() != 0:
        path.chmod(0o555)
        undo = lambda: path.chmod(0o755)  # noqa: E731
    else:
        if subprocess.run(["chattr", "+i", str(path)], check=False).returncode != 0:
            pytest.skip("chattr +i is not available here")
        undo = lambda: subprocess.run(["chattr", "-i", str(path)], check=True)  # noqa: E731
    try:
        yield
    finally:
        undo()


def test_6_read_only_run_directory(run_dir, capsys):
    before = snapshot(run_dir)
    with read_only(run_dir):
        assert main(["replay", str(run_dir)]) == 1
    assert "must be writable" in one_error_line(capsys.readouterr().err, "replay")
    assert snapshot(run_dir) == before


def test_6_ctrl_c_is_one_line_and_exit_130(run_dir, monkeypatch, capsys):
    def interrupted(file, **arrays):
        with open(file, "wb") as out:
            out.write(b"half of it")
        raise KeyboardInterrupt

    before = snapshot(run_dir)
    monkeypatch.setattr(np, "savez", interrupted)
    try:
        status = main(["learn", str(run_dir)])
    except KeyboardInterrupt:  # a traceback, not a message
        status = "KeyboardInterrupt"
    assert status == 130
    line = one_error_line(capsys.readouterr().err, "learn")
    assert "interrupted (Ctrl-C) in stage learn" in line
    assert snapshot(run_dir) == before


def test_6_ctrl_c_while_figures_are_drawn_stops_the_drawing_process_quietly(run_dir, in_a_terminal):
    """Ctrl-C reaches every process of the terminal's group: the process that draws the figures
    (started by the stage) leaves it to the stage, which stops it."""
    before = snapshot(run_dir)
    stage = _figures_with_its_drawing_process(in_a_terminal, run_dir, stderr=subprocess.PIPE)
    try:
        os.killpg(stage.pid, signal.SIGINT)
        _, err = stage.communicate(timeout=120)
    finally:
        stage.kill()
    assert stage.returncode == 130
    assert "interrupted (Ctrl-C) in stage figures" in one_error_line(err, "figures")
    assert snapshot(run_dir) == before
    assert _no_drawing_process_left(stage.pid)


def test_6_drawing_process_of_a_killed_stage_exits_by_itself(run_dir, in_a_terminal):
    stage = _figures_with_its_drawing_process(in_a_terminal, run_dir, stderr=subprocess.DEVNULL)
    stage.kill()
    stage.wait()
    assert _no_drawing_process_left(stage.pid)  # it looks for its parent every PARENT_POLL_S


def test_6_ctrl_c_while_the_drawing_process_starts_is_not_lost():
    """The stage starts its drawing process with SIGINT blocked (the process inherits it so); a
    Ctrl-C in that moment is raised once it has started. Ignored instead, it was lost: under
    load, a Ctrl-C there let the stage run to its end."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    held = False
    try:
        with pytest.raises(KeyboardInterrupt):  # raised as the block is left
            with drawing._holding_ctrl_c():
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.2)  # a signal not held would interrupt here
                held = True
        assert held
        with drawing.worker() as pool:
            (pid,) = pool._processes
            status = Path(f"/proc/{pid}/status").read_text()
        blocked = int(status.split("SigBlk:")[1].split()[0], 16)
        assert blocked & (1 << (signal.SIGINT - 1))
    finally:
        signal.signal(signal.SIGINT, previous)


def _figures_with_its_drawing_process(in_a_terminal, run_dir, stderr) -> subprocess.Popen:
    """``imitate figures run_dir`` started by ``in_a_terminal``, once its drawing process runs."""
    command = [sys.executable, "-m", "imitate", "figures", str(run_dir)]
    stage = in_a_terminal(command, stderr=stderr, text=True)
    for _ in range(600):  # up to 60 s
        if _drawing_processes(stage.pid):
            return stage
        time.sleep(0.1)
    stage.kill()
    raise AssertionError("no drawing process started within 60 s")


def _no_drawing_process_left(group: int) -> bool:
    """Whether process ``group``'s drawing processes are all gone within 10 s."""
    for _ in range(100):
        if not _drawing_processes(group):
            return True
        time.sleep(0.1)
    return False


def _drawing_processes(group: int) -> list[int]:
    """The pids of the multiprocessing workers in process ``group``."""
    pids = []
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        with contextlib.suppress(OSError):
            pid = int(cmdline.parent.name)
            if b"spawn_main" in cmdline.read_bytes() and os.getpgid(pid) == group:
                pids.append(pid)
    return pids


def test_6_sigterm_is_one_line_and_exit_143(run_dir, monkeypatch, capsys):
    def terminated(file, **arrays):
        with open(file, "wb") as out:
            out.write(b"half of it")
        os.kill(os.getpid(), signal.SIGTERM)

    received = []
    previous = signal.signal(signal.SIGTERM, lambda *_: received.append(1))  # not this process
    try:
        before = snapshot(run_dir)
        monkeypatch.setattr(np, "savez", terminated)
        assert main(["learn", str(run_dir)]) == 143
    finally:
        signal.signal(signal.SIGTERM, previous)
    line = one_error_line(capsys.readouterr().err, "learn")
    assert "terminated (SIGTERM) in stage learn" in line
    assert snapshot(run_dir) == before and not received


def test_a_symlinked_lock_is_refused_and_its_target_untouched(tmp_path):
    run_dir, victim = tmp_path / "run", tmp_path / "victim.txt"
    run_dir.mkdir()
    victim.write_text("mine")
    (run_dir / LOCK).symlink_to(victim)
    with pytest.raises(ImitateError, match=r"\.lock is a symbolic link; .* remove it"):
        with locked(run_dir, "imitate learn"):
            pass
    assert victim.read_text() == "mine" and (run_dir / LOCK).is_symlink()


def test_after_a_stage_re_runs_the_page_marks_what_is_out_of_date(run_dir, caplog):
    assert main(["optimize", str(run_dir), "--collision-weight", "5000"]) == 0
    page = (run_dir / "report.html").read_text()
    for command in ("replay", "figures"):
        files = table.find(command).files  # replay.npz; video.mp4, figures/*.png
        assert f"Out of date: {files} (made from another" in page
        assert f"<code>imitate {command} {run_dir}</code> makes it again" in page
        assert f"out of date: {files}" in caplog.text
    assert main(["replay", str(run_dir)]) == 0
    page = (run_dir / "report.html").read_text()
    assert "Out of date: replay.npz" not in page and "Out of date: video.mp4" in page


# --- a commit waits for no signal; a folder of something else is not taken for a run ------------


def learn_with_renames(run_dir, monkeypatch, at: dict) -> tuple[int, list[str]]:
    """``learn --k-max 5`` with ``at[n]()`` called just before its ``n``-th rename into
    ``run_dir``: its exit status and the names renamed (or tried)."""
    replace, renamed = os.replace, []

    def replace_calling(src, dst):
        if Path(dst).parent == run_dir:
            renamed.append(Path(dst).name)
            at.get(len(renamed), lambda: None)()
        replace(src, dst)

    with monkeypatch.context() as patched:
        patched.setattr(os, "replace", replace_calling)
        status = main(["-q", "learn", "--k-max", "5", str(run_dir)])
    return status, renamed


def terminate() -> None:
    os.kill(os.getpid(), signal.SIGTERM)


def fail_to_rename() -> None:
    raise OSError(errno.EIO, os.strerror(errno.EIO))


def test_sigterm_during_the_commit_comes_after_it_and_says_the_stage_was_saved(
    run_dir, monkeypatch, capsys
):
    status, renamed = learn_with_renames(run_dir, monkeypatch, {2: terminate})
    assert status == 143
    line = one_error_line(capsys.readouterr().err, "learn")
    assert line.endswith(f"terminated (SIGTERM) just after stage learn was saved in {run_dir}")
    assert renamed[-1] == provenance.MANIFEST
    report = json.loads((run_dir / "report.json").read_text())
    weights = np.load(run_dir / "model.npz")["weights"]
    assert report["learning"]["n_components"] == len(weights) <= 5
    config, manifest = load_config(run_dir), provenance.load(run_dir)
    assert config.k_max == 5 and provenance.stale(run_dir, table.find("optimize"), config,
                                                  manifest) == []


def test_sigterm_during_a_commit_that_fails_says_what_the_commit_replaced(
    run_dir, monkeypatch, capsys
):
    status, renamed = learn_with_renames(
        run_dir, monkeypatch, {2: terminate, 3: fail_to_rename}
    )
    assert status == 143
    line = one_error_line(capsys.readouterr().err, "learn")
    assert "terminated (SIGTERM) as stage learn failed: cannot rename" in line
    assert f"replaced: {', '.join(renamed[:2])}; not replaced" in line
    assert "changed nothing" not in line


def pretend_stages(monkeypatch) -> list[str]:
    """The stages a command would run, recorded instead of run."""
    from imitate.stages import runner

    ran = []

    def run_stage(stage, run_dir, config, force=False):
        ran.append(stage)
        return {"timings": dict.fromkeys(table.NAMES, 0.0)}

    monkeypatch.setattr(runner, "run_stage", run_stage)
    return ran


@pytest.mark.parametrize("command", ["observe", "run"])
def test_a_folder_of_another_tool_is_refused_unless_into_existing(
    tmp_path, command, monkeypatch, capsys
):
    ran = pretend_stages(monkeypatch)
    folder = tmp_path / "theirs"
    folder.mkdir()
    (folder / "config.json").write_text('{"lr": 0.1}\n')
    for name in ("a.txt", "b.txt", "notes"):
        (folder / name).write_text(name)
    before = snapshot(folder)
    assert main([command, "--quick", str(folder)]) == 1
    line = one_error_line(capsys.readouterr().err, command)
    assert line == (
        f"imitate {command}: error: {folder} holds a.txt, b.txt, config.json and 1 more and is "
        "not a run directory (no manifest.json); give another folder, or add --into-existing "
        "to start a run in it anyway (its files of the names a run writes, such as config.json, "
        "are replaced)"
    )
    assert snapshot(folder) == before and ran == []  # no lock either: nothing written
    assert main([command, "--quick", "--into-existing", str(folder)]) == 0
    assert ran == list(table.NAMES if command == "run" else ["observe"])


KILLED = json.dumps({"pid": 2**22 + 1, "host": "h", "command": "imitate run x", "since": "then"})


@pytest.mark.parametrize(("holds", "taken"), [
    (None, True),
    ({}, True),
    ({"manifest.json": "{}", "config.json": "{}"}, True),
    ({LOCK: KILLED, "config.json": "{}", ".demos.npz.12-ab.partial.npz": "half"}, True),
    ({LOCK: "held by their editor"}, False),
], ids=["missing", "empty", "run", "killed-run", "their-lock"])
def test_what_observe_takes_for_a_run_directory(tmp_path, holds, taken, monkeypatch, capsys):
    """Taken: a missing or empty folder, a run directory, a folder holding the ``.lock`` of an
    ``imitate`` command (a run killed before its first stage finished). Refused: another's."""
    ran = pretend_stages(monkeypatch)
    folder = tmp_path / "run"
    if holds is not None:
        folder.mkdir()
        for name, text in holds.items():
            (folder / name).write_text(text)
        before = snapshot(folder)
    assert main(["observe", "--quick", str(folder)]) == (0 if taken else 1)
    if taken:
        assert ran == ["observe"]
    else:
        assert "is not a run directory" in one_error_line(capsys.readouterr().err, "observe")
        assert snapshot(folder) == before and ran == []
