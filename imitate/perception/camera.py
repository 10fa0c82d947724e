"""The pinhole camera model and triangulation (the gaze frame of a camera is
:func:`imitate.taskspace.gaze_of_camera` of its :attr:`PinholeCamera.rotation`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PinholeCamera:
    """A calibrated camera in OpenCV's convention (x right, y down, z forward).

    Attributes:
        intrinsics: ``K`` ``(3, 3)`` [px]; pixel ``(col, row)`` of a pixel's centre is its index.
        rotation: ``(3, 3)`` world-to-camera rotation (rows: the camera axes in world coordinates).
        position: ``(3,)`` optical centre in the world frame [m].
        width: image width [px].
        height: image height [px].
    """

    intrinsics: np.ndarray
    rotation: np.ndarray
    position: np.ndarray
    width: int
    height: int

    @property
    def projection(self) -> np.ndarray:
        """``P = K [R | -R c]``, ``(3, 4)``."""
        return self.intrinsics @ np.hstack(
            [self.rotation, -(self.rotation @ self.position)[:, None]]
        )

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel coordinates ``(..., 2)`` of world points ``(..., 3)`` [m]."""
        cam = (np.asarray(points, dtype=float) - self.position) @ self.rotation.T
        pix = cam @ self.intrinsics.T
        return pix[..., :2] / pix[..., 2:]

    def directions(self, pixels: np.ndarray) -> np.ndarray:
        """Viewing directions ``(..., 3)`` (unit depth, not unit length) through ``pixels``.

        Args:
            pixels: ``(..., 2)`` ``(col, row)`` [px].

        Returns:
            World-frame vectors whose component along the optical axis is 1.
        """
        k = self.intrinsics
        pixels = np.asarray(pixels, dtype=float)
        x = (pixels[..., 0] - k[0, 2]) / k[0, 0]
        y = (pixels[..., 1] - k[1, 2]) / k[1, 1]
        r = self.rotation
        return x[..., None] * r[0] + y[..., None] * r[1] + r[2]


def triangulate(left: PinholeCamera, right: PinholeCamera, pl: np.ndarray, pr: np.ndarray):
    """Triangulation of corresponding pixels: the midpoint of the rays' closest approach.

    Args:
        left: first camera.
        right: second camera.
        pl: ``(..., 2)`` pixels in the first camera's image.
        pr: ``(..., 2)`` the corresponding pixels in the second camera's image.

    Returns:
        ``(..., 3)`` world points [m]; exact for exactly corresponding pixels.
    """
    d1, d2 = left.directions(pl), right.directions(pr)
    w0 = left.position - right.position
    a, b, c = (d1 * d1).sum(-1), (d1 * d2).sum(-1), (d2 * d2).sum(-1)
    d, e = d1 @ w0, d2 @ w0
    denom = a * c - b * b  # > 0 unless the rays are parallel (a point at infinity)
    t1, t2 = (b * e - c * d) / denom, (a * e - b * d) / denom
    return 0.5 * (left.position + t1[..., None] * d1 + right.position + t2[..., None] * d2)

