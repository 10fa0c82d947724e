"""Render a short headless video of the scene: the robot holds bottle and glass, its right wrist
turns, the teacher stands across the table; a caption on top. With ``--check``, decode the file
again and verify that the frames show both object colours, change over time and carry the
caption as written (exit status 1 if not).

    python scripts/ci/render_ci_video.py --out runs/ci/video.mp4 --width 160 --height 120 --check
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import imageio.v3 as iio
import numpy as np
from tqdm import tqdm

from imitate.envs.pour.env import PouringEnv
from imitate.envs.video import caption, caption_error
from imitate.models import humanoid, objects
from imitate.rundir.artifacts import write_atomic

WAVING_JOINTS = {"right_wrist_roll": 0.6, "right_wrist_pitch": 0.5, "right_elbow": 0.25}  # [rad]
CAPTION = "CI video"


def render(out: Path, width: int, height: int, seconds: float, fps: int) -> int:
    """Write the video to ``out`` (atomically); returns the number of frames."""
    env = PouringEnv(
        render_mode="rgb_array", width=width, height=height, particles=40, teacher=True,
        render_quality="full",  # a video for people
    )
    env.reset(seed=0)
    rest = env.data.ctrl.copy()
    joint_index = {name: humanoid.JOINTS.index(name) for name in WAVING_JOINTS}
    steps_per_frame = max(1, round(1.0 / (fps * env.dt)))
    n_frames = round(seconds * fps)
    frames = []
    for k in tqdm(range(n_frames), desc="rendering", unit="frame", disable=not sys.stderr.isatty()):
        phase = np.sin(2 * np.pi * k / n_frames)
        action = rest.copy()
        for name, amplitude in WAVING_JOINTS.items():
            action[joint_index[name]] += amplitude * phase
        for _ in range(steps_per_frame):
            env.step(action.astype(np.float32))
        frames.append(caption(env.render(), CAPTION))
    env.close()
    video = np.stack(frames)
    write_atomic(
        out, lambda tmp: iio.imwrite(tmp, video, fps=fps, codec="libx264", macro_block_size=8)
    )
    return n_frames


def colour_fraction(frame: np.ndarray, rgba) -> float:
    """Fraction of pixels of ``frame`` (h, w, 3) uint8 RGB whose hue is that of ``rgba``."""
    hsv = cv2.cvtColor(frame, cv2.COLOR_RGB2HSV)
    target = cv2.cvtColor(np.uint8([[np.array(rgba[:3]) * 255]]), cv2.COLOR_RGB2HSV)[0, 0]
    gap = np.abs(hsv[..., 0].astype(int) - int(target[0]))
    gap = np.minimum(gap, 180 - gap)  # OpenCV hue is 0..179
    return float(np.mean((gap < 8) & (hsv[..., 1] > 100) & (hsv[..., 2] > 50)))


def check(path: Path, expected_frames: int) -> list[str]:
    """Problems found in the decoded video (empty when it is fine)."""
    frames = iio.imread(path)
    problems = []
    if len(frames) != expected_frames:
        problems.append(f"{len(frames)} frames decoded, {expected_frames} written")
    for name, shape in (
        (objects.BOTTLE, objects.BOTTLE_SHAPE),
        (objects.GLASS, objects.GLASS_SHAPE),
    ):
        seen = min(colour_fraction(frame, shape.rgba) for frame in frames)
        if seen < 1e-4:
            problems.append(f"the {name}'s colour is missing from some frames ({seen:.1e})")
    change = np.abs(frames[0].astype(int) - frames[len(frames) // 2].astype(int)).mean()
    if change < 0.2:
        problems.append(f"frames do not change over time (mean abs difference {change:.3f})")
    error = max(caption_error(frame, CAPTION) for frame in frames)
    if error > 20.0:
        problems.append(f"the caption does not read as written (mean abs difference {error:.1f})")
    return problems


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("runs/ci/video.mp4"))
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--fps", type=int, default=15)
    parser.add_argument("--check", action="store_true", help="decode and verify the video")
    args = parser.parse_args(argv)
    if args.seconds <= 0 or args.fps <= 0:
        parser.error(f"--seconds {args.seconds} and --fps {args.fps} must be positive")
    n_frames = render(args.out, args.width, args.height, args.seconds, args.fps)
    print(f"wrote {args.out} ({n_frames} frames, {args.width}x{args.height})")
    if args.check:
        problems = check(args.out, n_frames)
        for problem in problems:
            print(f"check failed: {problem}", file=sys.stderr)
        if problems:
            return 1
        print("check passed: decodes, shows the bottle and the glass, frames change, caption reads")
    return 0


if __name__ == "__main__":
    sys.exit(main())
