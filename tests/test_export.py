"""``imitate export``: every format read back with its own reader and checked against the run."""

import importlib.util
import inspect
import json
import re
import shutil
from pathlib import Path

import cv2
import gymnasium as gym
import h5py
import imageio.v3 as iio
import minari
import mujoco
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import imitate
from imitate.cli import main
from imitate.envs import bimanual
from imitate.envs.pour.env import PouringEnv
from imitate.envs.rendering import make_renderer
from imitate.envs.task import get_task
from imitate.evaluation.variation import Variation
from imitate.export import export, to_hdf5, to_lerobot, to_minari
from imitate.export.episodes import (
    OBSTACLE,
    PLACES,
    robot_episode,
    teacher_episodes,
)
from imitate.models import humanoid
from imitate.motion.replay import replay
from imitate.perception.colour import object_models
from imitate.run import load_run
from imitate.stages import provenance

POUR = get_task("pour")  # the quick run's task
OBJECTS, TASK = POUR.objects, POUR.words.instruction
ROBOT_ID, TEACHER_ID = to_minari.dataset_ids(POUR.env_id)


@pytest.fixture(scope="module")
def run(quick_run):
    return load_run(quick_run)


def reset_options(run):
    return POUR.reset_options(run.config.options)


def check_robot(run, actions, rewards, pour_fraction, success, dt, atol=1e-12):
    """The episode is the replay stage's: the plan's targets, the same pour, the same outcome.

    ``pour_fraction`` and ``success`` are those after the last step; the bottle starts full.
    """
    plan, defaults = run.plan, inspect.signature(replay).parameters
    n_approach = round(defaults["approach"].default / dt)
    n_settle = round(defaults["settle"].default / dt)
    t_play = np.arange(0.0, plan.times[-1] - plan.times[0] + 1e-9, dt)
    play = np.column_stack([np.interp(t_play, plan.times - plan.times[0], q) for q in plan.q.T])
    assert len(actions) == n_approach + len(play) + n_settle
    # the actions lead the targets by their speed (the replay's feed-forward, linear): undo it
    lead = PouringEnv(particles=0).servo_lag + dt / 2
    speed = np.gradient(np.eye(len(actions)), dt, axis=0)  # np.gradient as a matrix
    targets = np.column_stack([
        np.linalg.solve(np.eye(len(actions)) + lag * speed, a)
        for lag, a in zip(lead, np.asarray(actions, dtype=float).T, strict=True)
    ])
    np.testing.assert_allclose(targets[n_approach - 1], plan.q_start, rtol=0, atol=atol)
    np.testing.assert_allclose(targets[n_approach:n_approach + len(play)], play, rtol=0, atol=atol)
    np.testing.assert_allclose(targets[-n_settle:] - plan.q[-1], 0.0, rtol=0, atol=atol)
    assert pour_fraction == run.replay.pour_fraction
    assert run.report["replay"]["min_distance_m"] >= 0.0  # no collision penalty, so:
    assert rewards.sum() == pytest.approx(pour_fraction, abs=1e-6)
    assert bool(success) == run.report["replay"]["success"]


def check_teacher(run, episodes):
    """``episodes``: per demonstration ``(observations, actions)``; one frame per camera frame,
    actions the next frame's object poses."""
    segments = run.demos.segments
    assert len(episodes) == len(segments)
    for (obs, actions), demo in zip(episodes, segments, strict=True):
        m = len(demo.times)
        assert {k: v.shape for k, v in obs.items()} == {k: (m, 7) for k in ("task", *OBJECTS)}
        np.testing.assert_array_equal(actions, np.hstack([obs[o] for o in OBJECTS])[1:])
        for o in OBJECTS:
            np.testing.assert_allclose(np.linalg.norm(obs[o][:, 3:], axis=1), 1.0, atol=1e-9)
        assert np.all(np.isfinite(obs["task"]))


def test_minari(run, tmp_path, monkeypatch):
    root = export(run.path, "minari", tmp_path / "minari")
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    assert (ROBOT_ID, TEACHER_ID) == ("imitate/pouring/robot-v0", "imitate/pouring/teacher-v0")
    robot = minari.load_dataset(ROBOT_ID)
    assert robot.total_episodes == 1
    episode = robot[0]
    spec = robot.spec.env_spec
    assert spec.id == imitate.ENV_ID and spec.entry_point == gym.spec(imitate.ENV_ID).entry_point
    assert spec.kwargs == {"particles": run.config.options["particles"], "obstacles": []}
    assert spec.max_episode_steps == len(episode.actions) == robot.total_steps
    assert episode.observations.shape == (len(episode.actions) + 1, 50)
    assert episode.truncations[-1] and not episode.truncations[:-1].any()
    assert not episode.terminations.any()
    env = robot.recover_environment()
    check_robot(
        run, episode.actions, episode.rewards, episode.infos["pour_fraction"][-1],
        episode.infos["is_success"][-1], env.unwrapped.dt,
    )
    assert episode.infos["pour_fraction"][0] == 0.0
    obs, _ = env.reset(seed=run.config.seed, options=reset_options(run))
    np.testing.assert_array_equal(obs, episode.observations[0])
    teacher = minari.load_dataset(TEACHER_ID)
    pyproject = (Path(__file__).parents[1] / "pyproject.toml").read_text()
    assert re.search(r'^name = "(.+)"$', pyproject, re.M)[1] == to_minari.DISTRIBUTION
    for dataset in (robot, teacher):
        metadata = dataset.storage.metadata
        assert metadata["requirements"] == [
            f"imitate-humanoid=={imitate.__version__}", f"mujoco=={mujoco.__version__}"
        ]
        assert metadata.get("code_permalink") is None  # no public release to point to
        assert f"code sha256 {provenance.code_digest()}." in metadata["description"]
        print(dataset.spec.dataset_id, {k: metadata.get(k) for k in (
            "requirements", "code_permalink", "total_episodes", "total_steps"
        )})
    assert teacher.spec.env_spec is None
    check_teacher(run, [(e.observations, e.actions) for e in teacher])
    for episode, demo in zip(teacher, run.demos.segments, strict=True):
        np.testing.assert_array_equal(episode.infos["time"], demo.times)


def test_hdf5(run, tmp_path):
    out = export(run.path, "hdf5", tmp_path / "hdf5")
    with h5py.File(out / "robot.hdf5", "r") as f:
        data = f["data"]
        env_args = json.loads(data.attrs["env_args"])
        assert (env_args["env_name"], env_args["type"]) == (imitate.ENV_ID, to_hdf5.GYM_TYPE)
        demo = data["demo_0"]
        n = int(demo.attrs["num_samples"])
        assert list(data) == ["demo_0"] and data.attrs["total"] == n
        assert (demo.attrs["seed"], json.loads(demo.attrs["options"])) == (
            run.config.seed, reset_options(run)
        )
        assert set(demo["obs"]) == set(demo["next_obs"]) == {"qpos", "qvel", *OBJECTS}
        for key in demo["obs"]:
            assert demo["obs"][key].shape[0] == demo["next_obs"][key].shape[0] == n
            np.testing.assert_array_equal(demo["obs"][key][1:], demo["next_obs"][key][:-1])
        dones = demo["dones"][()]
        assert dones[-1] == 1 and not dones[:-1].any()
        env = gym.make(env_args["env_name"], **env_args["env_kwargs"])
        assert env.spec.max_episode_steps == n
        check_robot(
            run, demo["actions"][()], demo["rewards"][()], demo["infos/pour_fraction"][-1],
            demo["infos/is_success"][-1], env.unwrapped.dt,
        )
        assert [list(f["mask"][k]) for k in ("train", "valid")] == [[b"demo_0"], []]
        states, spec = demo["states"][()], mujoco.mjtState(data.attrs["state_spec"])
        assert states.shape == (n, mujoco.mj_stateSize(env.unwrapped.model, spec))
        env.reset(seed=0)  # the stored states alone continue the physics, bit for bit:
        for k in (0, n // 2, n - 1):
            mujoco.mj_setState(env.unwrapped.model, env.unwrapped.data, states[k], spec)
            obs, *_ = env.step(demo["actions"][k])
            state = np.hstack([demo["next_obs"][key][k] for key in ("qpos", "qvel", *OBJECTS)])
            np.testing.assert_array_equal(obs, state)
        print("robot.hdf5:", {k: v.shape for k, v in demo.items() if hasattr(v, "shape")},
              "mask", {k: list(v) for k, v in f["mask"].items()})
    with h5py.File(out / "teacher.hdf5", "r") as f:
        demos = [f["data"][f"demo_{i}"] for i in range(len(f["data"]))]
        assert json.loads(f["data"].attrs["env_args"])["env_name"] is None
        check_teacher(run, [
            ({k: np.vstack([d["obs"][k], d["next_obs"][k][-1:]]) for k in d["obs"]},
             d["actions"][()])
            for d in demos
        ])
        for d, segment in zip(demos, run.demos.segments, strict=True):
            np.testing.assert_array_equal(d["infos/time"], segment.times[1:])
            assert "states" not in d  # no physics
        names = {f"demo_{i}".encode() for i in range(len(demos))}
        train, valid = (set(f["mask"][k]) for k in ("train", "valid"))
        assert train | valid == names and not train & valid
        assert len(valid) == int(to_hdf5.VALID_SHARE * len(demos))
        print("teacher.hdf5: demos", len(demos), "mask", {k: len(v) for k, v in f["mask"].items()})


def read_lerobot(root):
    """Checks a LeRobot v3.0 dataset's files against its ``meta/`` (as the spec lays them out,
    read with pyarrow); returns ``info``, each episode's columns as arrays and the episodes'
    table."""
    meta = root / "meta"
    info = json.loads((meta / "info.json").read_text())
    episodes = pq.read_table(meta / "episodes/chunk-000/file-000.parquet").to_pylist()
    tasks = pq.read_table(meta / "tasks.parquet")
    assert b"pandas" in tasks.schema.metadata  # the task string is the frame's index
    assert tasks.to_pylist() == [{"task_index": 0, "__index_level_0__": TASK}]
    assert info["codebase_version"] == "v3.0" and info["total_tasks"] == 1
    assert info["total_episodes"] == len(episodes)
    assert info["total_frames"] == sum(e["length"] for e in episodes)
    features = info["features"]
    columns = {k for k, f in features.items() if f["dtype"] != "video"}
    table = pq.read_table(root / info["data_path"].format(chunk_index=0, file_index=0))
    assert set(table.column_names) == columns and table.num_rows == info["total_frames"]
    data = {}
    for key in columns:  # a (1,) feature is a column of values, a (k,) one of k-lists
        column, shape = table[key].combine_chunks(), features[key]["shape"]
        value_type = pa.from_numpy_dtype(np.dtype(features[key]["dtype"]))
        if shape == [1]:
            assert column.type == value_type, key
            data[key] = column.to_numpy(zero_copy_only=False)
        else:
            assert column.type == pa.list_(value_type, shape[0]), key
            data[key] = column.flatten().to_numpy().reshape(-1, shape[0])
    np.testing.assert_array_equal(data["index"], np.arange(table.num_rows))
    stats = json.loads((meta / "stats.json").read_text())
    assert set(stats) == set(features)
    videos = {k: iio.imread(root / info["video_path"].format(
        video_key=k, chunk_index=0, file_index=0
    )) for k, f in features.items() if f["dtype"] == "video"}
    tables = []
    for i, episode in enumerate(episodes):
        start, stop = episode["dataset_from_index"], episode["dataset_to_index"]
        n = episode["length"]
        assert episode["episode_index"] == i and stop - start == n and episode["tasks"] == [TASK]
        arrays = {k: v[start:stop] for k, v in data.items()}
        np.testing.assert_array_equal(arrays["frame_index"], np.arange(n))
        np.testing.assert_array_equal(arrays["episode_index"], i)
        np.testing.assert_allclose(arrays["timestamp"], np.arange(n) / info["fps"], atol=1e-5)
        for key in columns:
            assert episode[f"stats/{key}/count"] == [n]
            np.testing.assert_allclose(
                episode[f"stats/{key}/mean"], arrays[key].reshape(n, -1).astype(float).mean(0)
            )
        for key, frames in videos.items():
            first = episode[f"videos/{key}/from_timestamp"] * info["fps"]
            assert round(first) == start and episode[f"videos/{key}/to_timestamp"] * info[
                "fps"] == pytest.approx(stop)
            arrays[key] = frames[start:stop]
            assert arrays[key].shape == (n, *features[key]["shape"])
        tables.append(arrays)
    assert all(len(frames) == info["total_frames"] for frames in videos.values())
    return info, tables, episodes


def test_lerobot(run, tmp_path):
    out = export(run.path, "lerobot", tmp_path / "lerobot")
    info, (robot,), _ = read_lerobot(out / "robot")
    assert info["fps"] == 50 and info["video_path"] is None
    assert info["features"]["action"]["names"] == list(humanoid.JOINTS)
    check_robot(
        run, robot["action"].astype(float), robot["next.reward"].astype(float),
        run.replay.pour_fraction, robot["next.success"][-1], 1 / info["fps"], atol=1e-6,
    )
    assert robot["next.done"][-1] and not robot["next.done"][:-1].any()
    robot_features = info["features"]
    info, teacher, _ = read_lerobot(out / "teacher")
    assert info["fps"] == run.config.fps
    features = info["features"]
    assert set(features) | {"next.success"} == set(robot_features)  # the teacher: no outcome
    environment = [f"{o}.{c}" for o in OBJECTS for c in ("x", "y", "z", "qw", "qx", "qy", "qz")]
    for f in (features, robot_features):
        assert f["observation.environment_state"]["names"] == environment
    assert features["action"]["names"] == environment  # the next frame's objects
    assert info["robot_type"] == "imitate_teacher"
    print("lerobot robot:", {k: f["names"][:3] for k, f in robot_features.items() if f["names"]})
    print("lerobot teacher:", {k: f["names"][:3] for k, f in features.items() if f["names"]})
    segments = run.demos.segments
    assert [len(t["action"]) for t in teacher] == [len(d.times) - 1 for d in segments]
    for name, count in (("robot", 1), ("teacher", len(segments))):  # the dataset cards
        card = (out / name / "README.md").read_text()
        front = card.split("---\n")[1]
        assert "license: apache-2.0" in front and "- LeRobot" in front
        assert f"{count} episode{'s' * (count != 1)}," in card and "muehlig2009" in card
        assert "`action`: float" in card


def fast_renderer(model, height, width, shadows=True):
    """``make_renderer`` without shadows and reflections: they cost ``PouringEnv`` ~0.1 s a frame
    on a CPU, whatever the image size."""
    renderer = make_renderer(model, height, width, shadows=False)
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
    return renderer


def test_images_in_every_format(quick_run, tmp_path, monkeypatch):
    """The robot's workspace camera and the teacher's stereo eyes, at 64x48, rendered fast: the
    robot's images show both objects in every frame."""
    monkeypatch.setattr(bimanual, "make_renderer", fast_renderer)
    run_dir = tmp_path / "run"
    shutil.copytree(quick_run, run_dir, ignore=shutil.ignore_patterns("*.mp4", "figures"))
    config = json.loads((run_dir / "config.json").read_text())
    (run_dir / "config.json").write_text(json.dumps({**config, "width": 64, "height": 48}))
    run = load_run(run_dir)
    robot = robot_episode(run, images=True)
    teacher = list(teacher_episodes(run, images=True))
    eyes = ("left_eye", "right_eye")
    assert robot.images == ("workspace",) and all(e.images == eyes for e in teacher)
    for episode in (robot, *teacher):
        for camera in episode.images:
            images = episode.observations[camera]
            assert images.shape == (len(episode) + 1, 48, 64, 3) and images.dtype == np.uint8
            assert images.std() > 5.0  # a scene, not a blank
    seen = np.array([visible(image) for image in robot.observations["workspace"]])
    assert np.all(seen > 0), seen.min(0)
    for name, module in (("minari", to_minari), ("hdf5", to_hdf5), ("lerobot", to_lerobot)):
        (tmp_path / name).mkdir()
        module.write(tmp_path / name, [robot], teacher)
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    for dataset_id, episodes in ((ROBOT_ID, [robot]), (TEACHER_ID, teacher)):
        for read, episode in zip(minari.load_dataset(dataset_id), episodes, strict=True):
            images = read.observations.get("pixels", read.observations)  # robot: as the env keys
            assert {c: images[c].shape for c in episode.images} == {
                c: episode.observations[c].shape for c in episode.images
            }
    with h5py.File(tmp_path / "hdf5" / "robot.hdf5", "r") as f:
        stored = f["data/demo_0/obs/workspace"][()]
    np.testing.assert_array_equal(stored, robot.observations["workspace"][:-1])
    for name, episodes in (("robot", [robot]), ("teacher", teacher)):
        _, read, _ = read_lerobot(tmp_path / "lerobot" / name)
        for arrays, episode in zip(read, episodes, strict=True):
            for camera in episode.images:  # H.264: near the images, not equal
                video = arrays[f"observation.images.{camera}"].astype(float)
                assert np.abs(video - episode.observations[camera][:-1]).mean() < 8.0


def visible(image):
    """Pixels ``(2,)`` of the bottle's and the glass's colours in an RGB image."""
    hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV)
    models = object_models(("bottle", "glass"))
    return np.array([np.count_nonzero(m.colour.mask(hsv)) for m in models])


def test_errors(run, tmp_path, monkeypatch):
    with pytest.raises(imitate.ImitateError, match=r"format 'csv' unknown; accepted"):
        export(run.path, "csv")
    (tmp_path / "taken").mkdir()
    with pytest.raises(imitate.ImitateError, match="taken exists"):
        export(run.path, "hdf5", tmp_path / "taken")
    taken = ["export", str(run.path), "--format", "hdf5", "--out", str(tmp_path / "taken")]
    assert main(taken) == 1
    find_spec = importlib.util.find_spec

    def without_minari(name, *args):
        return None if name == "minari" else find_spec(name, *args)

    monkeypatch.setattr(importlib.util, "find_spec", without_minari)
    hint = r"needs minari: pip install 'imitate-humanoid\[export"
    with pytest.raises(imitate.ImitateError, match=hint):
        export(run.path, "minari", tmp_path / "new")
    assert not (tmp_path / "new").exists()


def test_cli_export_and_nothing_half_written(run, tmp_path):
    out = tmp_path / "cli"
    assert main(["export", str(run.path), "--format", "hdf5", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["robot.hdf5", "teacher.hdf5"]
    assert [p.name for p in tmp_path.iterdir()] == ["cli"]  # no temporary left


def test_export_refuses_a_stale_plan_and_a_held_run_directory(quick_run, tmp_path):
    from imitate.errors import ImitateError
    from imitate.rundir.lock import locked

    run_dir = tmp_path / "run"
    shutil.copytree(quick_run, run_dir)
    config = json.loads((run_dir / "config.json").read_text())
    (run_dir / "config.json").write_text(json.dumps({**config, "collision_weight": 5.0}))
    with pytest.raises(ImitateError, match=r"optimize.*before exporting"):
        export(run_dir, "hdf5", out=tmp_path / "out")
    (run_dir / "config.json").write_text(json.dumps(config))
    with locked(run_dir, "imitate replay"), pytest.raises(ImitateError, match="in use by"):
        export(run_dir, "hdf5", out=tmp_path / "out")
    assert not (tmp_path / "out").exists() and not list(tmp_path.glob(".out.*"))


def test_minari_without_out_goes_into_minaris_datasets_root(quick_run, tmp_path, monkeypatch):
    root = tmp_path / "datasets"
    (root / "someone" / "else-v0").mkdir(parents=True)  # a root with other datasets
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    assert export(quick_run, "minari") == root.absolute()
    for dataset_id in (ROBOT_ID, TEACHER_ID):
        assert minari.load_dataset(dataset_id).total_episodes >= 1
    assert (root / "someone" / "else-v0").is_dir() and not list(root.glob(".*partial"))
    from imitate.errors import ImitateError

    with pytest.raises(ImitateError, match="robot-v0 exists; .*minari.delete_dataset"):
        export(quick_run, "minari")


@pytest.fixture(scope="module")
def evaluated_run(quick_run, tmp_path_factory):
    """A copy of the quick run and the folder of its evaluation in two variations."""
    from imitate.evaluation.suite import Suite
    from imitate.evaluation.suite_run import evaluate

    run_dir = tmp_path_factory.mktemp("evaluated") / "run"
    shutil.copytree(quick_run, run_dir, ignore=shutil.ignore_patterns("eval", "export"))
    suite = Suite.from_dict({"variations": 2, "max_iter": 5, "replays": 1, "particles": [4, 6]})
    evaluate(run_dir, suite, workers=1, videos=0, out=run_dir / "eval" / "tiny")
    return run_dir, run_dir / "eval" / "tiny"


def test_from_eval_one_episode_per_variation_whose_actions_replay_to_its_outcome(
    evaluated_run, tmp_path
):
    from imitate.evaluation.suite_run import last_records
    from imitate.export.from_eval import replayed

    run_dir, eval_dir = evaluated_run
    records = last_records(eval_dir)
    out = export(run_dir, "hdf5", tmp_path / "hdf5", from_eval=eval_dir)
    with h5py.File(out / "robot.hdf5", "r") as f:
        demos = [f["data"][f"demo_{i}"] for i in range(len(f["data"]))]
        assert len(demos) == len(records) == 2
        for demo, record in zip(demos, records, strict=True):
            metadata = json.loads(demo.attrs["metadata"])
            assert metadata["settings"] == record["settings"]
            assert (metadata["variation"], metadata["outcome"]) == (record["id"], record["outcome"])
            assert metadata["pour_fraction"] == record["replays"][0]["pour_fraction"]
            actions = demo["actions"][()]
            again = replayed(metadata, actions)
            assert again["pour_fraction"] == metadata["pour_fraction"]
            assert again["is_success"] == metadata["poured"] == demo["infos/is_success"][-1]
            assert demo["infos/pour_fraction"][-1] == metadata["pour_fraction"]
            variation = Variation.from_json(metadata["settings"])
            for place in PLACES:  # the obstacle and fixtures, observed at every step
                seen = demo["obs"][place][()]
                np.testing.assert_array_equal(seen, np.tile(seen[0], (len(seen), 1)))
                thing = getattr(variation, place)
                assert seen[0, 0] == (thing is not None)
                if thing is not None:
                    np.testing.assert_array_equal(seen[0, 2:5], thing.pos)
        hdf5_actions = [d["actions"][()] for d in demos]
    assert main(["export", str(run_dir), "--format", "lerobot", "--from-eval", str(eval_dir),
                 "--out", str(tmp_path / "lerobot")]) == 0
    info, tables, episodes = read_lerobot(tmp_path / "lerobot" / "robot")
    names = info["features"]["observation.environment_state"]["names"]
    assert names[14:] == [f"{p}.{c}" for p in PLACES for c in OBSTACLE]
    for arrays, episode, actions in zip(tables, episodes, hdf5_actions, strict=True):
        assert json.loads(episode["metadata"])["variation"] == episode["episode_index"]
        np.testing.assert_array_equal(arrays["action"], actions.astype(np.float32))


def test_from_eval_refuses_minari_and_an_evaluation_of_other_code(
    evaluated_run, tmp_path, monkeypatch
):
    from imitate.stages import provenance

    run_dir, eval_dir = evaluated_run
    with pytest.raises(imitate.ImitateError, match="from_eval=.* with format='minari'"):
        export(run_dir, "minari", tmp_path / "m", from_eval=eval_dir)
    with pytest.raises(imitate.ImitateError, match="summary.json is missing"):
        export(run_dir, "hdf5", tmp_path / "h", from_eval=run_dir / "eval")
    crafted = tmp_path / "crafted"
    shutil.copytree(eval_dir, crafted)
    (crafted / "summary.json").write_text(json.dumps({"teachers": []}))
    with pytest.raises(imitate.ImitateError, match="is not an evaluation's summary"):
        export(run_dir, "hdf5", tmp_path / "h", from_eval=crafted)
    summary = json.loads((eval_dir / "summary.json").read_text())
    summary["teachers"][0]["seed"] = "../../../outside"  # review X6a: into a path before
    (crafted / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(imitate.ImitateError, match="seeds .* are not all whole numbers"):
        export(run_dir, "hdf5", tmp_path / "h", from_eval=crafted)
    shutil.rmtree(crafted)
    monkeypatch.setattr(provenance, "code_digest", lambda: "other code")
    with pytest.raises(imitate.ImitateError, match="evaluated with another model .* or other code"):
        export(run_dir, "hdf5", tmp_path / "h", from_eval=eval_dir)
    assert not list(tmp_path.iterdir())


def test_lerobot_reads_the_export_offline(evaluated_run, tmp_path, monkeypatch):
    """LeRobot's own reader, where it is installed (not by this project: it needs torch)."""
    lerobot_dataset = pytest.importorskip("lerobot.datasets.lerobot_dataset")
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    run_dir, eval_dir = evaluated_run
    out = export(run_dir, "lerobot", tmp_path / "lerobot", from_eval=eval_dir)
    for name in ("robot", "teacher"):
        _, tables, _ = read_lerobot(out / name)
        dataset = lerobot_dataset.LeRobotDataset(f"local/{name}", root=out / name)
        assert dataset.num_episodes == len(tables)
        rows = np.vstack([t["action"] for t in tables])
        assert len(dataset) == len(rows)
        for i in (0, len(rows) // 2, len(rows) - 1):
            item = dataset[i]
            np.testing.assert_array_equal(item["action"].numpy(), rows[i])
            assert item["task"] == TASK
