"""Artifacts are written atomically and read back with errors that name the file; the run files
(:mod:`imitate.stages.files`) add the command that writes them again."""

import errno
import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from imitate.errors import ImitateError
from imitate.rundir import artifacts
from imitate.rundir.artifacts import (
    load_json,
    load_npz,
    remove_temporary,
    save_json,
    save_npz,
    staged,
    write_atomic,
)
from imitate.rundir.schema import load_report
from imitate.stages.files import DemosFile, ModelFile, PlanFile


def test_npz_round_trip(tmp_path):
    arrays = {"t": np.linspace(0, 1, 5), "x": np.arange(6).reshape(2, 3)}
    path = save_npz(tmp_path / "demos.npz", arrays)
    loaded = load_npz(path, required=("t", "x"))
    for name, value in arrays.items():
        np.testing.assert_array_equal(loaded[name], value)


def test_an_npz_that_would_inflate_beyond_the_bound_is_not_read(tmp_path, monkeypatch):
    """Review X9: a small file with a huge deflated member took gigabytes; the sizes its
    directory states are checked before any member is read."""
    import zipfile

    path = tmp_path / "model.npz"
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("bomb.npy", b"\0" * 4_000_000)  # 4 MB of zeros, 4 kB on disk
    assert path.stat().st_size < 20_000
    monkeypatch.setattr(artifacts, "MAX_NPZ_BYTES", 2**20)
    with pytest.raises(ImitateError, match=r"model.npz holds 4 MiB of arrays, more than imitate "
                                           r"writes \(at most 1 MiB\)"):
        load_npz(path)


def test_interrupted_write_leaves_nothing(tmp_path):
    path = tmp_path / "model.npz"

    def crash(tmp):
        tmp.write_bytes(b"half of it")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomic(path, crash)
    assert list(tmp_path.iterdir()) == []


def test_interrupted_rewrite_keeps_the_old_file(tmp_path):
    path = save_json(tmp_path / "report.json", {"seed": 1})
    with pytest.raises(RuntimeError):
        write_atomic(path, lambda tmp: (_ for _ in ()).throw(RuntimeError("disk full")))
    assert load_json(path) == {"seed": 1}


def test_a_missing_file_is_named_with_the_hint_given(tmp_path):
    path = tmp_path / "model.npz"
    with pytest.raises(ImitateError) as error:
        load_npz(path)
    assert str(error.value) == f"{path} is missing"
    with pytest.raises(ImitateError, match=r"model.npz is missing; make it$"):
        load_npz(path, hint="make it")


def test_missing_run_file_names_file_and_stage(tmp_path):
    with pytest.raises(ImitateError, match=r"model.npz is missing; re-run `imitate learn"):
        ModelFile.load(tmp_path)


def test_corrupt_run_file_names_file_and_stage(tmp_path):
    (tmp_path / "plan.npz").write_bytes(b"not a zip file")
    with pytest.raises(ImitateError, match=r"plan.npz is corrupt .* `imitate optimize"):
        PlanFile.load(tmp_path)
    (tmp_path / "report.json").write_text("{truncated")
    with pytest.raises(ImitateError, match=r"report.json is corrupt .*delete it"):
        load_report(tmp_path / "report.json")


def test_missing_array_is_named(tmp_path):
    save_npz(tmp_path / "demos.npz", {"t": np.zeros(3)})
    with pytest.raises(ImitateError, match=r"lacks \['objects', 'gaze', 'boundaries'\]; re-run `"
                       r"imitate observe"):
        DemosFile.load(tmp_path)


def test_array_read_but_not_required_is_named_with_the_hint(tmp_path):
    save_npz(tmp_path / "plan.npz", {"times": np.zeros(3)})
    plan = load_npz(tmp_path / "plan.npz", required=("times",), hint="re-run it")
    with pytest.raises(ImitateError, match=r"lacks 'sweep2_cost_total'; re-run it"):
        plan["sweep2_cost_total"]


def test_staged_files_appear_together_when_the_block_ends(tmp_path):
    with staged(tmp_path) as staging:
        save_json(tmp_path / "report.json", {"seed": 1})
        save_npz(tmp_path / "figures" / "model.npz", {"x": np.zeros(2)})
        assert list(staging.files()) == ["report.json", "figures/model.npz"]
        assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")) == []
    assert load_json(tmp_path / "report.json") == {"seed": 1}
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["figures", "model.npz", "report.json"]


def test_staged_files_vanish_when_the_block_raises(tmp_path):
    save_json(tmp_path / "report.json", {"seed": 1})
    with pytest.raises(KeyboardInterrupt), staged(tmp_path):
        save_json(tmp_path / "report.json", {"seed": 2})
        save_npz(tmp_path / "figures" / "model.npz", {"x": np.zeros(2)})
        raise KeyboardInterrupt
    assert load_json(tmp_path / "report.json") == {"seed": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["report.json"]


def test_nothing_is_written_through_a_symbolic_link(tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "figures").symlink_to(outside)
    (run_dir / "report.json").symlink_to(outside / "victim.json")
    (outside / ".a.partial.json").write_text("a user's file")
    for path in (run_dir / "figures" / "fig.png", run_dir / "report.json"):
        with pytest.raises(ImitateError, match="is a symbolic link; imitate writes nothing"):
            with staged(run_dir):
                save_json(path, {"x": 1})
    assert sorted(p.name for p in outside.iterdir()) == [".a.partial.json"]
    assert remove_temporary(run_dir) == [] and (outside / ".a.partial.json").exists()
    linked = tmp_path / "latest"  # the run directory itself may be a link: the user chose it
    linked.symlink_to(run_dir)
    with staged(linked):
        save_json(linked / "config.json", {"x": 1})
    assert (run_dir / "config.json").is_file()


def test_commit_checks_every_destination_before_the_first_rename(tmp_path):
    (tmp_path / "figures").write_text("a file where the folder goes")
    with pytest.raises(ImitateError, match="figures is in the way of fig.png: remove it"):
        with staged(tmp_path, last="manifest.json"):
            save_json(tmp_path / "manifest.json", {"m": 1})
            save_json(tmp_path / "report.json", {"r": 1})
            save_json(tmp_path / "figures" / "fig.png", {"f": 1})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figures"]


def test_the_manifest_is_renamed_last(tmp_path, monkeypatch):
    import os

    renamed = []
    replace = os.replace
    monkeypatch.setattr(os, "replace", lambda a, b: (renamed.append(os.path.basename(b)),
                                                     replace(a, b)))
    with staged(tmp_path, last="manifest.json"):
        save_json(tmp_path / "manifest.json", {"m": 1})
        save_json(tmp_path / "model.npz", {"a": 1})
        save_json(tmp_path / "report.json", {"r": 1})
    assert renamed == ["model.npz", "report.json", "manifest.json"]


COMMITTED = ("model.npz", "config.json", "report.json", "manifest.json")  # in commit order


def commit_over_old_files(run_dir, replace):
    """Stage and commit new versions of :data:`COMMITTED` over old ones in ``run_dir``, with
    ``replace(src, dst)`` doing its renames."""
    for name in COMMITTED:
        save_json(run_dir / name, {"old": name})
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(os, "replace", replace)
        with staged(run_dir, last="manifest.json"):
            for name in COMMITTED:
                save_json(run_dir / name, {"new": name})


class Stop(Exception):
    """What the tests' signal handler raises."""


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
@pytest.mark.parametrize("sender", ["process", "thread"])
def test_a_signal_during_the_commit_waits_for_its_last_rename(tmp_path, signum, sender):
    idle = threading.Event()
    other = threading.Thread(target=idle.wait)  # "thread": the kernel hands the signal to it
    other.start()
    replace, renamed = os.replace, []

    def replace_and_signal(src, dst):
        renamed.append(os.path.basename(dst))
        if len(renamed) == 2:
            if sender == "process":
                os.kill(os.getpid(), signum)
            else:
                signal.pthread_kill(other.ident, signum)
                time.sleep(0.2)  # time for that thread to take it, mid-commit
        replace(src, dst)

    seen = {}

    def handler(n, frame):
        seen.update({name: load_json(tmp_path / name) for name in COMMITTED})
        raise Stop

    previous = signal.signal(signum, handler)
    try:
        with pytest.raises(Stop):
            commit_over_old_files(tmp_path, replace_and_signal)
            # A signal sent to another thread is taken when the kernel runs that thread, which
            # under load may be after the commit: the handler runs then.
            deadline = time.monotonic() + 10.0
            while time.monotonic() < deadline:
                time.sleep(0.01)
        assert signal.getsignal(signum) is handler
    finally:
        signal.signal(signum, previous)
        idle.set()
        other.join()
    assert renamed == list(COMMITTED)
    assert seen == {name: {"new": name} for name in COMMITTED}  # when the handler ran
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(COMMITTED)  # no temporary


def test_a_rename_failing_midway_names_what_it_replaced(tmp_path):
    replace, renamed = os.replace, []

    def replace_or_fail(src, dst):
        renamed.append(os.path.basename(dst))
        if len(renamed) == 3:
            raise OSError(errno.EIO, os.strerror(errno.EIO), dst)
        replace(src, dst)

    with pytest.raises(ImitateError) as error:
        commit_over_old_files(tmp_path, replace_or_fail)
    assert str(error.value) == (
        f"cannot rename report.json into place in {tmp_path} (Input/output error); replaced: "
        "model.npz, config.json; not replaced, kept as they were: report.json, manifest.json; "
        "run the command again"
    )
    assert {name: load_json(tmp_path / name) for name in COMMITTED} == {
        "model.npz": {"new": "model.npz"}, "config.json": {"new": "config.json"},
        "report.json": {"old": "report.json"}, "manifest.json": {"old": "manifest.json"},
    }
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(COMMITTED)  # no temporary


def test_deeply_nested_json_is_corrupt_in_one_line(tmp_path):
    path = tmp_path / "report.json"
    path.write_text("[" * 200_000)
    with pytest.raises(ImitateError, match=r"report\.json is corrupt"):
        load_json(path)


def test_a_file_this_user_may_not_read_is_not_called_corrupt(tmp_path, monkeypatch):
    save_npz(tmp_path / "model.npz", {"x": np.zeros(2)})
    save_json(tmp_path / "report.json", {})

    def denied(*args, **kwargs):  # as open() of a file of mode 600 that another user owns
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES))

    monkeypatch.setattr(np, "load", denied)
    monkeypatch.setattr(Path, "read_text", denied)
    for path, load in ((tmp_path / "model.npz", load_npz), (tmp_path / "report.json", load_json)):
        with pytest.raises(ImitateError, match=r"cannot be read by this user .*chmod u\+r"):
            load(path)
