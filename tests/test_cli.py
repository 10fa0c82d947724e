"""The ``imitate`` command end to end: ``imitate run --quick``, its report, determinism, errors."""

import json
import re
import shutil

import imageio.v3 as iio
import numpy as np
import pytest

from imitate.cli import main
from imitate.cli.parser import COMMANDS, build_parser, stages_of
from imitate.errors import ImitateError
from imitate.rundir.artifacts import load_npz
from imitate.stages.config import RunConfig, settings

NPZ = ("observations.npz", "demos.npz", "model.npz", "plan.npz", "replay.npz")
FIGURES = (
    "observation", "fig4_gmm_dtw", "fig5_bic", "gmr", "fig8_snapshots", "fig9_collision_sweep",
    "costs",
)


def report_of(run_dir):
    return json.loads((run_dir / "report.json").read_text())


def without_timings(report):
    """The report less what depends on the machine's speed."""
    report = {k: v for k, v in report.items() if k != "timings"}
    report["learning"] = {k: v for k, v in report["learning"].items() if k != "seconds"}
    report["optimization"] = {k: v for k, v in report["optimization"].items() if k != "seconds"}
    report["perception"] = {
        k: v for k, v in report["perception"].items() if not k.endswith("_per_s")
    }
    return report


def test_quick_run_report(quick_run):
    r = report_of(quick_run)
    assert r["seed"] == 0
    assert r["demos"]["detected"] == r["demos"]["expected"] == RunConfig.quick().n_demos
    assert r["demos"]["boundary_err_s_max"] < 0.6
    assert r["perception"]["pos_err_mm_median"] < 10.0
    assert r["perception"]["pos_err_mm_p95"] < 30.0
    assert r["perception"]["angle_err_deg_median"] < 3.0
    learning, k_max = r["learning"], RunConfig.quick().k_max
    assert learning["n_components"] == learning[f"n_components_{learning['bic']}_bic"]
    assert 2 <= learning["n_components"] <= k_max
    assert 1 <= learning["n_components_fast_bic"] <= k_max
    opt = r["optimization"]
    assert opt["iterations"] >= 1 and np.isfinite(opt["min_distance_m"])
    assert opt["min_distance_m"] > 0.0, opt["message"]
    weights = [entry["weight"] for entry in opt["sweep"]]
    assert weights == sorted(weights) and opt["collision_weight"] in weights
    assert 0.0 <= r["replay"]["pour_fraction"] <= 1.0
    assert r["replay"]["pour_fraction_min"] <= r["replay"]["pour_fraction_mean"] <= 1.0
    assert r["replay"]["success"] == (
        r["replay"]["pour_fraction_min"] >= 0.9 and r["replay"]["min_distance_m"] >= 0.0
    )
    assert set(r["timings"]) == {"observe", "learn", "optimize", "replay", "figures"}
    for name in r["artifacts"].values():
        assert (quick_run / name).is_file(), name


def test_quick_run_pours(quick_run):
    r = report_of(quick_run)["replay"]
    assert r["pour_fraction"] >= 0.9 and r["spilled"] <= 3 and r["success"], r


def test_quick_run_figures_and_video_are_not_blank(quick_run):
    for name in FIGURES:
        image = iio.imread(quick_run / "figures" / f"{name}.png")
        assert image.std() > 5.0, name
    video = iio.imread(quick_run / "video.mp4")
    assert len(video) == report_of(quick_run)["video"]["frames"]
    assert video.std() > 5.0 and np.abs(np.diff(video[::10].astype(float), axis=0)).mean() > 0.1


def test_same_seed_same_report_and_arrays(quick_run, tmp_path):
    assert main(["run", "--quick", "--out", str(tmp_path)]) == 0
    assert without_timings(report_of(tmp_path)) == without_timings(report_of(quick_run))
    for name in NPZ:
        first, second = load_npz(quick_run / name), load_npz(tmp_path / name)
        assert first.keys() == second.keys(), name
        for key in first:
            assert first[key].tobytes() == second[key].tobytes(), f"{name}:{key}"


def test_later_stage_reuses_artifacts_and_keeps_settings(quick_run, tmp_path):
    run_dir = tmp_path / "rerun"
    shutil.copytree(quick_run, run_dir)
    assert main(["optimize", str(run_dir), "--collision-weight", "30", "--max-iter", "5"]) == 0
    r = report_of(run_dir)
    config = json.loads((run_dir / "config.json").read_text())
    assert config["collision_weight"] == 30.0 and config["n_demos"] == RunConfig.quick().n_demos
    assert r["optimization"]["collision_weight"] == 30.0
    pushed = "null-space push" in r["optimization"]["message"]
    assert r["optimization"]["iterations"] <= (17 if pushed else 5)  # 3 runs of 5 with the push
    assert "replay" not in r and r["learning"] == report_of(quick_run)["learning"]


def test_missing_artifact_names_file_and_stage(tmp_path, capsys):
    (tmp_path / "config.json").write_text(json.dumps(RunConfig.quick().to_json()))
    assert main(["optimize", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "model.npz is missing" in err and "imitate learn" in err


def test_corrupt_artifact_names_file_and_stage(quick_run, tmp_path, capsys):
    run_dir = tmp_path / "corrupt"
    shutil.copytree(quick_run, run_dir)
    (run_dir / "plan.npz").write_bytes(b"not a zip file")
    assert main(["replay", str(run_dir)]) == 1
    err = capsys.readouterr().err
    assert "plan.npz is not the file `imitate optimize` wrote" in err
    assert main(["replay", str(run_dir), "--force"]) == 1
    err = capsys.readouterr().err
    assert "plan.npz is corrupt" in err and "imitate optimize" in err


def test_recorded_states_that_do_not_fit_the_scene_are_one_line(quick_run, tmp_path, capsys):
    run_dir = tmp_path / "cut"
    shutil.copytree(quick_run, run_dir)
    arrays = dict(np.load(run_dir / "replay.npz"))
    np.savez(run_dir / "replay.npz", **{**arrays, "qpos": arrays["qpos"][:, :5]})
    assert main(["figures", str(run_dir), "--force"]) == 1
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("imitate figures: error:") and "holds qpos of shape" in err
    assert "re-run imitate replay" in err


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["run", "--demos", "1"], "n_demos=1 not accepted: a value in 2..20"),
        (["run", "--collision-weight", "-1"], "collision_weight=-1.0 not accepted"),
        (["run", "--particles", "500"], "particles=500 not accepted: a whole number in 1..120"),
        (["run", "--obstacle", "box:9,9,9:0.1,0.1,0.1"], "outside the table"),
        (["run", "--obstacle", "sphere"], "box:X,Y,Z:SX,SY,SZ"),
        (["run", "--bottle-grasp", "2"], "bottle_grasp=2.0 not accepted: a number in 0.05..0.13"),
        (["run", "--task", "insert", "--particles", "30"],
         "particles (--particles) not a setting of task 'insert'"),
        (["run", "--demos", "two"], "invalid int value"),
        (["run", "--bic", "slow"], "invalid choice: 'slow'"),
    ],
)
def test_bad_flag_values_are_refused(argv, expected, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert expected in capsys.readouterr().err
    assert not (tmp_path / "config.json").exists()


def test_cli_knows_every_stage_in_order():
    from imitate.stages.table import NAMES

    assert tuple(COMMANDS) == (*NAMES, "run", "export", "eval", "compare", "sensitivity")
    parser = build_parser()
    for command in COMMANDS:
        args, _ = parser.parse_known_args([command, "RUN_DIR", "--format", "hdf5"])
        assert args.command == command and args.parser.prog == f"imitate {command}"


def test_config_round_trips_through_json():
    from imitate.envs.assembly import Obstacle

    config = RunConfig.quick(obstacle=Obstacle("box", (0.55, 0.0, 0.70), (0.03, 0.03, 0.05)))
    assert RunConfig.from_json(json.loads(json.dumps(config.to_json()))) == config


def test_help_states_the_real_defaults():
    defaults, parser, shown = RunConfig(), build_parser(), set()
    for command in (*stages_of("run"), "run"):
        page = "".join(parser.parse_known_args([command])[0].parser.format_help().split())
        for name, setting, default in settings([None, *stages_of(command)]):
            if setting.flag is None:
                continue
            text = setting.describe(default)
            assert "".join(text.split()) in page, (command, setting.flag)
            shown.add(name)
            expected = getattr(defaults, name)
            if expected is None:  # --obstacle: no obstacle unless given
                continue
            stated = re.search(r"\(default (\S+)\)", text)
            assert stated, setting.flag
            if isinstance(expected, bool):
                assert stated.group(1) == ("--" if expected else "--no-") + name
            elif isinstance(expected, str):
                assert stated.group(1) == expected, setting.flag
            else:
                assert float(stated.group(1)) == expected, setting.flag
    assert shown >= {"n_demos", "k_max", "collision_weight", "video_width"}


def test_a_task_settings_help_states_each_tasks_range_and_default():
    """Review: ``--glass-grasp`` showed pour's default (0.05) for insert too (0.03)."""
    from imitate.envs import tasks

    page = " ".join(build_parser().parse_known_args(["run"])[0].parser.format_help().split())
    for task in tasks.NAMES:
        for name, option in tasks.options(task).items():
            if option.stage in stages_of("run"):
                stated = f"{task} {option.low:g}..{option.high:g}, default {option.default:g}"
                assert stated in page, (task, name)


def test_settings_refuse_values_outside_the_range_their_help_states():
    for name, setting, default in settings():
        if setting.low is None:
            continue
        assert setting.bounds() in setting.describe(default)
        bad = setting.low - 1
        accepted = re.escape(setting.bounds())
        with pytest.raises(ImitateError, match=rf"{name}=.* not accepted: .*{accepted}"):
            RunConfig(**{name: (bad,) if isinstance(default, tuple) else bad})


def test_interrupted_stage_leaves_no_half_written_file(quick_run, tmp_path, monkeypatch):
    run_dir = tmp_path / "interrupted"
    shutil.copytree(quick_run, run_dir)
    (run_dir / "model.npz").unlink()

    def interrupted(file, **arrays):
        with open(file, "wb") as out:
            out.write(b"half of it")
        raise KeyboardInterrupt

    monkeypatch.setattr(np, "savez", interrupted)
    assert main(["learn", str(run_dir)]) == 130
    assert not (run_dir / "model.npz").exists()
    assert not [p.name for p in run_dir.iterdir() if "partial" in p.name]


def test_a_mistyped_flag_gets_one_line_and_a_suggestion(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["optimize", str(tmp_path), "--colision-weight", "30"])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and err == (
        "imitate optimize: error: unrecognized arguments: --colision-weight (did you mean "
        "--collision-weight?) 30\n"
    )


def test_a_new_run_over_another_names_the_settings_it_replaces(tmp_path, caplog):
    from imitate.cli.commands import _warn_if_replaced
    from imitate.rundir.artifacts import save_json

    save_json(tmp_path / "config.json", RunConfig.quick().to_json())
    _warn_if_replaced(tmp_path, RunConfig())
    assert "holds a run made with other settings" in caplog.text
    assert "n_demos 3 -> 5" in caplog.text and "width 320 -> 640" in caplog.text
    caplog.clear()
    _warn_if_replaced(tmp_path, RunConfig.quick())
    _warn_if_replaced(tmp_path / "none", RunConfig())
    assert caplog.text == ""


def test_eval_of_a_missing_run_writes_nothing(tmp_path, capsys):
    assert main(["eval", str(tmp_path / "nope"), "--n", "1"]) == 1
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("imitate eval: error: run directory") and "not found" in err
    assert not (tmp_path / "nope").exists()


def test_a_report_of_another_schema_is_refused_in_one_line(quick_run, tmp_path):
    import imitate

    run_dir = tmp_path / "run"
    shutil.copytree(quick_run, run_dir)
    report = report_of(run_dir)
    (run_dir / "report.json").write_text(json.dumps({**report, "schema": 99}))
    with pytest.raises(ImitateError, match="has schema 99; this imitate reads and writes schema 1"):
        _ = imitate.load_run(run_dir).report
    assert main(["figures", str(run_dir)]) == 1


HEAVY = ("mujoco", "numba", "scipy", "matplotlib", "cv2", "trimesh")


@pytest.mark.parametrize("command", ["", "observe", "learn", "optimize", "replay", "figures",
                                     "run", "export", "eval", "compare"])
def test_help_loads_no_heavy_module(command):
    """Every ``--help`` builds its parser from plain constants and the settings' declarations
    (under a second): none of MuJoCo, numba, SciPy, matplotlib, OpenCV or trimesh loads. Its
    time is printed (``pytest -s``), not asserted: a loaded machine is slower."""
    import subprocess
    import sys
    import time

    code = (
        "import sys, runpy\n"
        f"sys.argv = ['imitate', *{command.split()!r}, '--help']\n"
        "try:\n    runpy.run_module('imitate', run_name='__main__')\n"
        "except SystemExit:\n    pass\n"
        f"print(sorted(m for m in {HEAVY!r} if m in sys.modules), file=sys.stderr)\n"
    )
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    print(f"imitate {command} --help: {time.perf_counter() - start:.2f} s")
    assert "usage: imitate" in done.stdout
    assert done.stderr.strip().splitlines()[-1] == "[]"


def test_progress_off_a_terminal_is_log_lines(caplog, capsys, monkeypatch):
    """Where stderr is not a terminal (as under pytest), a bar is INFO lines, no bar drawing,
    none at the end of a work shorter than the lines' interval; below INFO (``-q``) nothing."""
    import logging

    from imitate.stages import progress as module
    from imitate.stages.progress import Lines, bar

    caplog.set_level(logging.INFO, logger="imitate")
    assert list(bar(range(3), desc="observe")) == [0, 1, 2] and not caplog.records
    monkeypatch.setattr(module, "LINE_INTERVAL", 0.0)
    with bar(total=5, desc="observe", unit="pair") as progress:
        assert isinstance(progress, Lines)
        progress.update(5)
    assert [r.getMessage()[:24] for r in caplog.records] == ["observe: 100% (5/5 pair)"]
    assert "\r" not in capsys.readouterr().err
    caplog.clear()
    caplog.set_level(logging.WARNING, logger="imitate")
    assert list(bar(range(3), desc="observe")) == [0, 1, 2] and not caplog.records


def test_first_compile_outside_the_warm_up_says_so(tmp_path):
    import os
    import subprocess
    import sys

    code = ("import numpy as np\nfrom imitate.learning import dtw\n"
            "dtw.local_costs(np.zeros((3, 2)), np.ones((2, 2)))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)})
    assert done.stderr.count("numba compiles imitate's kernels on first use") == 1
    again = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           check=True, env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)})
    assert "numba compiles" not in again.stderr  # loaded from the cache


def test_an_error_keeps_a_paths_spaces_on_one_line(tmp_path, capsys):
    folder = tmp_path / "run with  two spaces"
    assert main(["learn", str(folder)]) == 1
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("imitate learn: error: ") and f"`imitate run --out {folder}`" in line


@pytest.mark.parametrize(
    ("error", "status", "line"),
    [
        (ImitateError("similarities='variance,flat' not accepted: two or more"), 1,
         "--similarity variance,flat not accepted: two or more"),
        (ImitateError("from_eval='e v' with format='minari' not accepted"), 1,
         "--from-eval e v with --format minari not accepted"),
        (OSError(28, "No space left on device"), 1,
         "[Errno 28] No space left on device; nothing was written"),
        (KeyboardInterrupt(), 130, "interrupted (Ctrl-C); nothing was written"),
        ("SIGTERM", 143, "terminated (SIGTERM); nothing was written"),
    ],
)
def test_every_command_exits_through_one_mapping(error, status, line, capsys):
    """A command's failure is one line naming the flags (not the library's parameters), with
    status 1 for an ImitateError or OSError, 130 for Ctrl-C and 143 for SIGTERM."""
    import os
    import signal

    from imitate.cli.commands import exits

    with exits("export", "nothing was written") as outcome:
        if error == "SIGTERM":
            os.kill(os.getpid(), signal.SIGTERM)
        else:
            raise error
    assert outcome.status == status
    assert capsys.readouterr().err == f"imitate export: error: {line}\n"
