"""The pouring task as a :class:`~imitate.envs.task.Task` (``TASK``)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from imitate.envs.pour.env import PouringEnv
from imitate.envs.pour.geometry import PourGeometry
from imitate.envs.pour.options import ENV_ID
from imitate.envs.pour.outcome import OUTCOMES, SUCCESS_FRACTION, outcome
from imitate.envs.task import Score, Task
from imitate.rundir.page import shown

__all__ = ["TASK", "pour_phase"]


def pour_phase(mean: np.ndarray) -> np.ndarray:
    """Steps ``(T,) bool`` where the bottle is tilted beyond 80 % of its largest tilt from the
    start, given the GMR mean ``(T, 7)``: the low-variance pouring phase."""
    tilt = np.abs(mean[:, 3] - mean[0, 3])
    return tilt >= 0.8 * tilt.max()


def headline(replay: Mapping[str, Any]) -> list[tuple[str, str]]:
    """The run page's headline row of the pour, from the report's replay section."""
    return [(
        "pour fraction",
        f"{shown(replay['pour_fraction'], '.2f')} (mean "
        f"{shown(replay['pour_fraction_mean'], '.2f')}, min "
        f"{shown(replay['pour_fraction_min'], '.2f')} over the replays), "
        f"{shown(replay['spilled'], 'g')} spilled",
    )]


def exported(record: Mapping[str, Any], info: Mapping[str, Any]) -> dict[str, Any]:
    """An exported evaluated episode's pouring metadata: the evaluation's smallest pour over
    the variation's replays (``pour_min``), this episode's pour fraction and whether it poured
    (the env's ``is_success``)."""
    return {
        "pour_min": record["pour_min"], "pour_fraction": float(info["pour_fraction"]),
        "poured": bool(info["is_success"]),
    }


# The report keys the pouring task adds to the replay section: unit and meaning.
KEYS = {
    "replay.pour_fraction": (
        "1",
        "fraction of the particles in the glass at the end of the replay",
    ),
    "replay.spilled": ("-", "particles in neither container at the end"),
    "replay.pour_fraction_mean": (
        "1",
        "mean pour fraction over three replays from seeds `seed`, `seed + 1`, `seed + 2` of the "
        "initial-state noise",
    ),
    "replay.pour_fraction_min": ("1", "the smallest of them"),
    "replay.pour_fractions": ("1", "the three"),
    "replay.pour_geometry.mouth_above_rim_min_m": (
        "m",
        "in the first replay, while liquid leaves the bottle: the lowest height of the bottle's "
        "mouth above the glass rim, in the glass's frame",
    ),
    "replay.pour_geometry.mouth_above_rim_median_m": ("m", "its median"),
    "replay.pour_geometry.mouth_offset_median_m": (
        "m",
        "median distance of the mouth from the glass's axis (the inner rim radius is 40 mm)",
    ),
    "replay.pour_geometry.mouth_offset_max_m": ("m", "its largest"),
    "replay.pour_geometry.tilt_max_deg": ("deg", "the bottle's largest tilt from upright"),
    "replay.pour_geometry.pour_seconds": (
        "s",
        "from the first to the last step at which liquid left the bottle",
    ),
    "replay.pour_geometry.stream_offset_median_m": (
        "m",
        "median distance from the glass's axis at which the particles first fell through the rim's"
        " plane",
    ),
    "replay.pour_geometry.stream_centre_offset_m": (
        "m",
        "distance of their mean crossing point from the axis",
    ),
    "replay.pour_geometry.stream_inside_share": (
        "1",
        "share of them that fell through within the rim's inner radius",
    ),
}

TASK = Task(
    name="pour",
    env=PouringEnv,
    env_id=ENV_ID,
    phase="pour",
    outcomes=OUTCOMES,
    measures={
        "pour_fraction": ("1", "fraction of the particles in the glass at the end"),
        "spilled": ("-", "particles in neither container at the end"),
    },
    keys=KEYS,
    outcome=outcome,
    critical=pour_phase,
    watcher=PourGeometry,
    suites=Path(__file__).parent / "suites",
    score=Score("pour_fraction", SUCCESS_FRACTION, "pour"),
    verbs=("pours", "does not pour"),
    noun="the pour",
    instruction="pour from the bottle into the glass",
    headline=headline,
    kinds={"replay.spilled": int, "replay.pour_fractions": list},
    exported=exported,
)
