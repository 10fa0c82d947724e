"""The robot's stereo perception: it tracks a task's objects in its head cameras' images.

:mod:`~imitate.perception.camera` (pinhole model, triangulation),
:mod:`~imitate.perception.colour` (what the robot knows of the objects: colours and shapes),
:mod:`~imitate.perception.tracker` (the stereo tracker; its docstring describes the method),
:mod:`~imitate.perception.tracks` (tracks over a sequence, gaps, the observation as arrays).
Nothing here knows the simulation: images and camera parameters come in as arrays
(:mod:`imitate.perception.watch` wires it to the simulated session).
"""

from imitate.perception.camera import PinholeCamera, triangulate
from imitate.perception.colour import SKIN, ColourRange, ObjectModel, colour_range, object_models
from imitate.perception.tracker import (
    Measurement,
    PerceptionConfig,
    StereoTracker,
    ViewMeasurement,
    perception_config,
)
from imitate.perception.tracks import (
    Gap,
    GroundTruth,
    Observations,
    Tracks,
    fill_gaps,
    track,
    tracks_from_ends,
)

__all__ = [
    "SKIN",
    "ColourRange",
    "Gap",
    "GroundTruth",
    "Measurement",
    "ObjectModel",
    "Observations",
    "PerceptionConfig",
    "PinholeCamera",
    "StereoTracker",
    "Tracks",
    "ViewMeasurement",
    "colour_range",
    "fill_gaps",
    "object_models",
    "perception_config",
    "track",
    "tracks_from_ends",
    "triangulate",
]
