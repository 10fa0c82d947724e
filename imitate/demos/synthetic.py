"""Seeded synthetic bimanual demonstrations in task space, with known structure.

Stands in for the observed teacher in tests and benchmarks. Every demonstration follows one
canonical movement over a phase variable ``s`` in [0, 1]:

- transport (``s < act_start``): the tool moves from beside the target to above it along a
  path bent by a per-demonstration via-point offset (large inter-demonstration spread);
- act (``act_start <= s < act_end``): the tool tilts towards the target and back, at a nearly
  fixed pose (small spread);
- return: the tool goes back down beside the target (moderate spread).

Each demonstration runs the canonical movement through its own smooth, monotone time warp and
has its own duration, so raw demonstrations disagree in time (Fig. 4, left) until DTW aligns
them. Object positions and long axes are generated in the world frame and mapped through
:data:`imitate.taskspace.EQ1`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imitate.errors import ImitateError
from imitate.taskspace import EQ1, gaze_frame

__all__ = ["SyntheticConfig", "SyntheticDemos", "phased_demos"]


@dataclass(frozen=True)
class SyntheticConfig:
    """Parameters of :func:`phased_demos`.

    Attributes:
        n_demos: Number of demonstrations.
        duration: Mean duration of a demonstration [s].
        duration_spread: Relative standard deviation of the durations.
        rate: Sampling rate [Hz].
        act_start: Phase at which the act starts, in (0, act_end).
        act_end: Phase at which the act ends, in (act_start, 1).
        transport_spread: Standard deviation of the transport via-point offset [m].
        act_spread: Standard deviation of the acting pose [m], tilt spread 5x this [rad].
        return_spread: Standard deviation of the final resting offset [m].
        warp: Amplitude of the time warps, in [0, 0.5) (monotone by construction).
        noise: Standard deviation of the measurement noise [m] (and 5x [rad] on the axes).
        tilt: Maximum tilt of the tool while acting [rad].
        seed: Seed of the random draws.
    """

    n_demos: int = 5
    duration: float = 4.5
    duration_spread: float = 0.06
    rate: float = 100.0
    act_start: float = 0.45
    act_end: float = 0.8
    transport_spread: float = 0.04
    act_spread: float = 0.003
    return_spread: float = 0.02
    warp: float = 0.3
    noise: float = 0.0005
    tilt: float = 1.9
    seed: int = 0


@dataclass(frozen=True)
class SyntheticDemos:
    """Output of :func:`phased_demos`.

    Attributes:
        demos: Task-space demonstrations, each of shape ``(n_steps_i, 7)``.
        act_windows: Start and end of the act in each demonstration's own time,
            shape ``(n_demos, 2)`` [s].
        gaze: Gaze frame used for the orientations, shape ``(3, 3)``, columns right, down,
            forward (:mod:`imitate.taskspace`).
        rate: Sampling rate [Hz].
    """

    demos: tuple[np.ndarray, ...]
    act_windows: np.ndarray
    gaze: np.ndarray
    rate: float


def _smoothstep(u: np.ndarray) -> np.ndarray:
    """Minimum-jerk profile from 0 to 1 on [0, 1], clipped outside."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u**2)


def _bump(u: np.ndarray) -> np.ndarray:
    """Smooth bump, 0 at the ends of [0, 1] and 1 in the middle, 0 outside."""
    u = np.clip(u, 0.0, 1.0)
    return np.sin(np.pi * u) ** 2


def phased_demos(config: SyntheticConfig | None = None) -> SyntheticDemos:
    """Generates seeded three-phase (transport, act, return) demonstrations in task space.

    Args:
        config: Parameters; ``None`` for the defaults (5 demonstrations of about 4.5 s at 100 Hz).

    Returns:
        The :class:`SyntheticDemos`.

    Raises:
        ImitateError: On inconsistent parameters.
    """
    c = config or SyntheticConfig()
    if c.n_demos < 1 or c.rate <= 0 or c.duration <= 0:
        raise ImitateError(f"n_demos, rate and duration must be positive; got {c}")
    if not 0.0 < c.act_start < c.act_end < 1.0:
        raise ImitateError(
            f"need 0 < act_start < act_end < 1; got {c.act_start} and {c.act_end}"
        )
    if not 0.0 <= c.warp < 0.5:
        raise ImitateError(f"warp must be in [0, 0.5); got {c.warp}")
    rng = np.random.default_rng(c.seed)
    gaze = gaze_frame([np.cos(0.5), 0.0, -np.sin(0.5)])  # looking ahead and 29 deg down
    target = np.array([0.45, 0.05, 0.85])
    start = np.array([-0.02, -0.28, -0.02])  # tool relative to target
    above = np.array([0.0, -0.07, 0.13])
    rest = np.array([0.0, -0.22, -0.02])

    demos, windows = [], []
    for _ in range(c.n_demos):
        duration = c.duration * (1.0 + c.duration_spread * rng.standard_normal())
        n = max(int(round(duration * c.rate)), 2)
        tau = np.linspace(0.0, 1.0, n)
        a1, a2 = rng.uniform(-c.warp, c.warp, size=2)
        s = tau + a1 * np.sin(2 * np.pi * tau) / (2 * np.pi) + a2 * np.sin(4 * np.pi * tau) / (
            4 * np.pi
        )  # ds/dtau >= 1 - |a1| - |a2| > 0: monotone, fixed ends

        via = rng.normal(0.0, c.transport_spread, 3)
        act_pose = above + rng.normal(0.0, c.act_spread, 3)
        rest_pose = rest + rng.normal(0.0, c.return_spread, 3)
        u_transport = s / c.act_start
        u_act = (s - c.act_start) / (c.act_end - c.act_start)
        u_return = (s - c.act_end) / (1.0 - c.act_end)
        rel = (
            start
            + _smoothstep(u_transport)[:, None] * (act_pose - start)
            + _bump(u_transport)[:, None] * via
            + _smoothstep(u_return)[:, None] * (rest_pose - act_pose)
        )
        target_sway = rng.normal(0.0, 0.3 * c.transport_spread, 3)
        target_pos = target + _bump(u_transport)[:, None] * target_sway

        tilt = (c.tilt + 5 * c.act_spread * rng.standard_normal()) * _bump(u_act)
        lean = 0.15 * _bump(u_transport) * rng.standard_normal()
        a_tool = np.column_stack((np.sin(lean), np.sin(tilt), np.cos(tilt) * np.cos(lean)))
        wobble = 0.05 * _bump(u_transport) * rng.standard_normal()
        a_target = np.column_stack((np.zeros(n), -np.sin(wobble), np.cos(wobble)))

        noise = c.noise * rng.standard_normal((4, n, 3))
        x = EQ1({"tool": (target_pos + rel + noise[0], a_tool + 5 * noise[1]),
                 "target": (target_pos + noise[2], a_target + 5 * noise[3])}, gaze)
        demos.append(x)
        t = tau * (n - 1) / c.rate
        windows.append(np.interp([c.act_start, c.act_end], s, t))
    return SyntheticDemos(
        demos=tuple(demos), act_windows=np.array(windows), gaze=gaze, rate=c.rate
    )
