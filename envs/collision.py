"""Pairs of geoms that must not touch, and their signed distances from ``mj_geomDistance``.

A pair is kept once, at construction, when MuJoCo would not already ignore it for the robot:
geoms of the same body, of bodies welded together, of a parent and its child (unless one of
them is welded to the world: a free object still collides with the table and the obstacles,
as in MuJoCo's parent filter), and pairs the model excludes explicitly (a hand and the object
it holds) are dropped. A tool that goes into its target (the bodies its text :data:`INSIDE`
names) keeps clear of the target's walls, not of its solid hulls: the pairs of the tool with the
target's hulls are dropped, and the target's physical geoms (walls and floor, among ``geoms``)
pair with the tool alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

# Name of a model text ``"tool target"``: the body names of a tool that goes into its target.
INSIDE = "clearance_inside"


@dataclass(frozen=True)
class CollisionPairs:
    """Geom pairs checked for clearance.

    Attributes:
        geom1: ``(n_pairs,)`` geom ids.
        geom2: ``(n_pairs,)`` geom ids.
    """

    geom1: np.ndarray
    geom2: np.ndarray

    def __len__(self) -> int:
        return len(self.geom1)

    def names(self, model: mujoco.MjModel, index: int) -> tuple[str, str]:
        """Names of the two geoms of pair ``index``."""
        return model.geom(int(self.geom1[index])).name, model.geom(int(self.geom2[index])).name

    def fixed(self, model: mujoco.MjModel) -> np.ndarray:
        """``(n_pairs,)`` whether a pair has a geom fixed in the world (the table, an obstacle)."""
        weld = model.body_weldid[model.geom_bodyid]
        return (weld[self.geom1] == 0) | (weld[self.geom2] == 0)

    @classmethod
    def between(cls, model: mujoco.MjModel, geoms: Sequence[int]) -> CollisionPairs:
        """All pairs among ``geoms`` (ids) that may come into contact and must not."""
        excluded = {int(s) for s in model.exclude_signature}
        tool, target = inside(model) or (-1, -1)
        wall = model.geom_contype != 0  # of the target's geoms: its walls, not its hulls
        geom_body = model.geom_bodyid
        weld = model.body_weldid
        parent = model.body_parentid
        first, second = [], []
        ids = sorted(set(int(g) for g in geoms))
        for i, g1 in enumerate(ids):
            for g2 in ids[i + 1 :]:
                b1, b2 = int(geom_body[g1]), int(geom_body[g2])
                w1, w2 = int(weld[b1]), int(weld[b2])
                p1, p2 = int(weld[parent[w1]]), int(weld[parent[w2]])
                if w1 == w2 or (w1 and w2 and (p1 == w2 or p2 == w1)):
                    continue
                # MuJoCo's exclude signature packs the two body ids as (min << 16) + max.
                if (min(b1, b2) << 16) + max(b1, b2) in excluded:
                    continue
                walls = [g for g, b in ((g1, b1), (g2, b2)) if b == target and wall[g]]
                if ({b1, b2} == {tool, target} and not walls) or (walls and tool not in (b1, b2)):
                    continue
                first.append(g1)
                second.append(g2)
        return cls(np.array(first, dtype=int), np.array(second, dtype=int))


def inside(model: mujoco.MjModel) -> tuple[int, int] | None:
    """The body ids ``(tool, target)`` of a tool that goes into its target (``model``'s text
    :data:`INSIDE`), ``None`` where there is none."""
    text = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TEXT, INSIDE)
    if text < 0:
        return None
    start = model.text_adr[text]
    tool, target = bytes(model.text_data[start : start + model.text_size[text] - 1]).split()
    return model.body(tool.decode()).id, model.body(target.decode()).id


def signed_distances(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    pairs: CollisionPairs,
    distmax: float = 0.2,
) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance of each pair at ``data``'s current kinematics.

    Args:
        model: the compiled model the geom ids refer to.
        data: its state, with the kinematics (geom poses) already computed.
        pairs: the geom pairs to measure.
        distmax: distances beyond this are reported as ``distmax`` [m] (faster).

    Returns:
        ``dist (n_pairs,)`` [m], negative when penetrating, and ``fromto (n_pairs, 6)``: the two
        witness points [m] in the world frame.
    """
    dist = np.full(len(pairs), distmax)
    fromto = np.zeros((len(pairs), 6))
    # A pair whose bounding spheres lie more than distmax apart is at distmax, as MuJoCo says
    # (a plane's bound is 0: unbounded).
    bound1, bound2 = model.geom_rbound[pairs.geom1], model.geom_rbound[pairs.geom2]
    gap = np.linalg.norm(data.geom_xpos[pairs.geom1] - data.geom_xpos[pairs.geom2], axis=1)
    near = (gap - bound1 - bound2 <= distmax) | (bound1 == 0) | (bound2 == 0)
    for k in np.flatnonzero(near):
        dist[k] = mujoco.mj_geomDistance(
            model, data, int(pairs.geom1[k]), int(pairs.geom2[k]), distmax, fromto[k]
        )
    return dist, fromto
