"""The video: its frames rendered in one thread or several, and x264 presets and qualities on
them (time, quality, size).

    python scripts/bench/bench_video.py [RUN_DIR] [--repeats 2] [--render [--threads N ...]]

Decodes ``RUN_DIR/video.mp4`` (default ``runs/latest``) once and encodes its frames again with
each encoder setting below, interleaved ``--repeats`` times: imageio's default for H.264 (x264's
medium preset at quality 5 of 10) and the settings of ``imitate.envs.video.ENCODER`` among
others. Prints the wall time, the encoder's processor time (ffmpeg, a child process), the mean
PSNR against the frames encoded (every 10th frame) and the file's size.

With ``--render``, first renders the run's video frames as the figures stage does (not encoded)
in 1 thread and in ``imitate.stages.figures.VIDEO_THREADS`` (or in each of ``--threads``),
interleaved
``--repeats`` times: the wall time, this process's processor time, and whether the frames are
those of the first thread count.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import tempfile
import time
from pathlib import Path

import imageio.v2 as imageio
import numpy as np

from imitate.envs.video import ENCODER
from imitate.stages import figures
from imitate.stages.config import RunConfig
from imitate.stages.files import ObservationsFile, PlanFile, ReplayFile


def x264(preset: str, quality: int) -> dict:
    """imageio.get_writer's keyword arguments for x264's ``preset`` at ``quality`` (0-10)."""
    return {"codec": "libx264", "quality": quality, "ffmpeg_params": ["-preset", preset]}


SETTINGS = {
    "medium, quality 5 (imageio's default)": {"codec": "libx264", "quality": 5},
    "veryfast, quality 5": x264("veryfast", 5),
    "veryfast, quality 6 (ENCODER)": ENCODER,
    "faster, quality 6": x264("faster", 6),
}


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """Peak signal-to-noise ratio [dB] of ``b`` against ``a``, 8-bit images."""
    mse = np.mean((a.astype(float) - b.astype(float)) ** 2)
    return float(10 * np.log10(255.0**2 / mse))


def encode(frames: list[np.ndarray], path: Path, fps: float, settings: dict) -> dict:
    cpu, start = children_cpu(), time.perf_counter()
    writer = imageio.get_writer(path, fps=fps, macro_block_size=8, **settings)
    for frame in frames:
        writer.append_data(frame)
    writer.close()
    wall, cpu = time.perf_counter() - start, children_cpu() - cpu
    decoded = [frame for frame in imageio.get_reader(path)]
    assert len(decoded) == len(frames), (len(decoded), len(frames))
    quality = np.mean([psnr(a, b) for a, b in zip(frames[::10], decoded[::10], strict=True)])
    return {"wall": wall, "cpu": cpu, "psnr": quality, "mb": path.stat().st_size / 1e6}


def render(run_dir: Path, threads: int) -> dict:
    """The run's video frames rendered as the figures stage does, in ``threads`` threads."""
    config = RunConfig.from_json(json.loads((run_dir / "config.json").read_text()))
    states = ReplayFile.load(run_dir)  # the replay and the weight-0 one
    plan = PlanFile.load(run_dir)
    observations = ObservationsFile.load(run_dir).observations
    figures.VIDEO_THREADS, threads_before = threads, figures.VIDEO_THREADS
    digest = hashlib.sha256()
    cpu, start = time.process_time(), time.perf_counter()
    count = 0
    try:
        for frame in figures._video_frames(config, states, observations, plan):
            digest.update(frame.tobytes())
            count += 1
    finally:
        figures.VIDEO_THREADS = threads_before
    return {"wall": time.perf_counter() - start, "cpu": time.process_time() - cpu,
            "frames": count, "digest": digest.hexdigest()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", nargs="?", type=Path, default=Path("runs/latest"))
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--render", action="store_true",
                        help="first render the frames in 1 thread and in VIDEO_THREADS")
    parser.add_argument("--threads", type=int, nargs="+", metavar="N",
                        help="with --render: these thread counts (default: 1 and VIDEO_THREADS)")
    args = parser.parse_args()
    counts = args.threads or [1, figures.VIDEO_THREADS]
    if min(counts) < 1:
        parser.error(f"--threads {counts} not accepted: counts of at least 1")
    if args.render:
        print(f"{'rendering the frames':40s} {'wall [s]':>9s} {'cpu [s]':>8s} {'frames/s':>9s}"
              f"  same frames as {counts[0]} thread(s)")
        one = None
        for _ in range(args.repeats):
            for threads in counts:
                r = render(args.run_dir, threads)
                one = one or r["digest"]
                print(f"{f'{threads} thread(s)':40s} {r['wall']:9.2f} {r['cpu']:8.2f} "
                      f"{r['frames'] / r['wall']:9.1f}  {r['digest'] == one}")
    reader = imageio.get_reader(args.run_dir / "video.mp4")
    fps = reader.get_meta_data()["fps"]
    frames = [frame for frame in reader]  # list() would ask its length: inf
    height, width = frames[0].shape[:2]
    print(f"{len(frames)} frames {width}x{height} at {fps:g} fps from {args.run_dir / 'video.mp4'};"
          f" {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
    print(f"{'encoder':40s} {'wall [s]':>9s} {'cpu [s]':>8s} {'PSNR [dB]':>10s} {'MB':>6s}")
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeats):
            for name, settings in SETTINGS.items():
                r = encode(frames, Path(tmp) / "video.mp4", fps, settings)
                print(
                    f"{name:40s} {r['wall']:9.2f} {r['cpu']:8.2f} {r['psnr']:10.2f} "
                    f"{r['mb']:6.2f}"
                )


if __name__ == "__main__":
    main()
