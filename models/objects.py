"""The objects as MjSpec bodies (their data: :mod:`imitate.models.shapes`).

Each container is a body whose frame sits at the centre of its bottom, ``z`` along its long axis.
It has one uniformly coloured visual mesh (a surface of revolution made by trimesh), hidden
collision geoms (a ring of boxes per wall segment, so it is hollow), and hidden ``*_hull``
geoms, simple convex stand-ins used for signed-distance queries: one upright cylinder per wall
segment that encloses its boxes (the first one the floor too), so a positive distance between
hulls means the collision geoms are apart too.
"""

from __future__ import annotations

import mujoco
import numpy as np
import trimesh

from imitate.models.shapes import (  # noqa: F401  (the objects' data, re-exported)
    BOTTLE,
    BOTTLE_SHAPE,
    GLASS,
    GLASS_SHAPE,
    GRASP_RANGE,
    MARKER,
    MARKER_SHAPE,
    SHAPES,
    STICK,
    STICK_SHAPE,
    ContainerShape,
)

# Visual and hidden groups of mujoco.Renderer's default scene options (groups 0-2 are drawn).
VISUAL_GROUP, COLLISION_GROUP, HULL_GROUP = 1, 3, 4
# contype/conaffinity bits: everything physical collides with everything physical.
PHYSICAL = 1
# Stiff contacts (time constant = 2 physics steps) so fast particles cannot sink through a wall.
STIFF_SOLREF = (0.004, 1.0)
FLOOR_THICKNESS = 0.012  # [m] of the collision floor, below the visual one: a safety margin


def container_mesh(shape: ContainerShape) -> trimesh.Trimesh:
    """Closed surface of the vessel (outer wall, rim, inner wall, floor), revolved about z."""
    half = shape.wall / 2
    outer = [(r + half, z) for r, z in shape.profile]
    inner = [(r - half, max(z, shape.wall)) for r, z in reversed(shape.profile)]
    outline = [(0.0, 0.0), *outer, *inner, (0.0, shape.wall)]
    return trimesh.creation.revolve(np.asarray(outline), sections=48)


def add_container(
    spec: mujoco.MjSpec, parent: mujoco.MjsBody, name: str, shape: ContainerShape,
    fixed: bool = False,
):
    """Add a container body ``name`` under ``parent``, free-floating unless ``fixed``; returns
    the body."""
    body = parent.add_body(name=name)
    if not fixed:
        body.add_freejoint(name=name)
    mesh = container_mesh(shape)
    spec.add_mesh(
        name=name,
        uservert=mesh.vertices.astype(np.float32).ravel(),
        userface=mesh.faces.astype(np.int32).ravel(),
    )
    body.add_geom(
        name=f"{name}_visual",
        type=mujoco.mjtGeom.mjGEOM_MESH,
        meshname=name,
        rgba=shape.rgba,
        contype=0,
        conaffinity=0,
        group=VISUAL_GROUP,
        density=0,
    )
    wall_geoms = 0
    # per wall segment: the corners (8 per box, 3) of its boxes [m]
    corners: list[list[np.ndarray]] = []
    for (r0, z0), (r1, z1) in zip(shape.profile[:-1], shape.profile[1:], strict=True):
        length, tilt = np.hypot(r1 - r0, z1 - z0), np.arctan2(r1 - r0, z1 - z0)
        radius = (r0 + r1) / 2
        half_chord = (radius + shape.wall) * np.tan(np.pi / shape.segments) * 1.05
        corners.append([])
        for i in range(shape.segments):
            angle = 2 * np.pi * i / shape.segments
            quat = np.zeros(4)
            mujoco.mju_mulQuat(quat, _axis_angle((0, 0, 1), angle), _axis_angle((0, 1, 0), tilt))
            size = (shape.wall / 2, half_chord, length / 2 + shape.wall / 2)
            pos = (radius * np.cos(angle), radius * np.sin(angle), (z0 + z1) / 2)
            corners[-1].append(_box_corners(pos, quat, size))
            body.add_geom(
                name=f"{name}_wall_{wall_geoms}",
                type=mujoco.mjtGeom.mjGEOM_BOX,
                size=size,
                pos=pos,
                quat=quat,
                group=COLLISION_GROUP,
                contype=PHYSICAL,
                conaffinity=PHYSICAL,
                rgba=shape.rgba,
                solref=STIFF_SOLREF,
            )
            wall_geoms += 1
    bottom_radius = shape.profile[0][0] + shape.wall / 2
    floor_bottom = shape.wall - FLOOR_THICKNESS
    body.add_geom(
        name=f"{name}_floor",
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        size=(bottom_radius, FLOOR_THICKNESS / 2, 0),
        pos=(0, 0, floor_bottom + FLOOR_THICKNESS / 2),
        group=COLLISION_GROUP,
        contype=PHYSICAL,
        conaffinity=PHYSICAL,
        rgba=shape.rgba,
        solref=STIFF_SOLREF,
    )
    for i, ((_, z0), (_, z1)) in enumerate(
        zip(shape.profile[:-1], shape.profile[1:], strict=True)
    ):
        if z1 - z0 < 1e-6:
            continue
        points = np.vstack(corners[i])
        low, high = points[:, 2].min(), points[:, 2].max()
        radius = np.hypot(points[:, 0], points[:, 1]).max()
        if i == 0:
            low, radius = min(low, floor_bottom), max(radius, bottom_radius)
        body.add_geom(
            name=f"{name}_hull_{i}",
            type=mujoco.mjtGeom.mjGEOM_CYLINDER,
            size=(radius, (high - low) / 2, 0),
            pos=(0, 0, (low + high) / 2),
            group=HULL_GROUP,
            contype=0,
            conaffinity=0,
            density=0,
            rgba=(1, 1, 1, 0.2),
        )
    return body


def _box_corners(pos, quat, size) -> np.ndarray:
    """``(8, 3)`` corners [m] of a box: centre ``pos`` (3,), ``quat`` (4,), half ``size`` (3,)."""
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, np.asarray(quat, dtype=float))
    local = np.array(np.meshgrid(*[[-s, s] for s in size])).reshape(3, -1).T
    return np.asarray(pos) + local @ rot.reshape(3, 3).T


def _axis_angle(axis, angle: float) -> np.ndarray:
    quat = np.zeros(4)
    mujoco.mju_axisAngle2Quat(quat, np.asarray(axis, dtype=float), angle)
    return quat
