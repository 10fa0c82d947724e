"""The video's encoding: x264 presets and qualities on a run's frames, time, quality and size.

    python scripts/bench_video.py [RUN_DIR] [--repeats 2]

Decodes ``RUN_DIR/video.mp4`` (default ``runs/latest``) once and encodes its frames again with
each encoder setting below, interleaved ``--repeats`` times: imageio's default for H.264 (x264's
medium preset at quality 5 of 10) and the settings of ``imitate.envs.video.ENCODER`` among
others. Prints the wall time, the encoder's processor time (ffmpeg, a child process), the mean
PSNR against the frames encoded (every 10th frame) and the file's size.
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from pathlib import Path

import imageio.v2 as imageio
import numpy as np

from imitate.envs.video import ENCODER


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", nargs="?", type=Path, default=Path("runs/latest"))
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
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
