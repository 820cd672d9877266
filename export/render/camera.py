"""A camera that looks at a subject along −x (DESIGN.md §3), fitted to its bounds, square image.

Pixel (i, j) of an R×R image: row i = 0 is the top (+z), column j = 0 is the left (−y). Rays go
through pixel centres.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from relight_rt.engine.errors import RelightError

from .scene import Subject

KINDS = ("orthographic", "perspective")
# Camera framings (issue 22): the fraction of the subject's height, from the top, that the square image shows.
# Anything below is cut by the image's bottom border, as in the photos people take.
FRAMINGS = {"full": 1.0, "knees-up": 0.72, "waist-up": 0.5, "head-shoulders": 0.27, "face": 0.14}


@dataclass(frozen=True)
class Camera:
    """Orthographic or perspective camera on the +x side of the subject, looking along −x.

    Attributes:
        kind: "orthographic" or "perspective".
        resolution: image size R (the image is R×R).
        center: (y, z) of the image centre in the subject frame, metres.
        half_extent: half the side of the square seen, metres (at the subject's depth ``depth_x``
            for a perspective camera).
        eye_x: x of the image plane (orthographic) or of the eye (perspective), metres; in front
            of everything.
        depth_x: x of the plane that ``half_extent`` refers to (the subject's centre).
    """

    kind: str
    resolution: int
    center: tuple[float, float]
    half_extent: float
    eye_x: float
    depth_x: float

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> Camera:
        return cls(
            kind=str(d["kind"]),
            resolution=int(d["resolution"]),
            center=(float(d["center"][0]), float(d["center"][1])),
            half_extent=float(d["half_extent"]),
            eye_x=float(d["eye_x"]),
            depth_x=float(d["depth_x"]),
        )

    def rays(self) -> tuple[np.ndarray, np.ndarray]:
        """Primary rays through every pixel centre, row-major.

        Returns:
            (origins, directions): each (R*R, 3) float32; directions are unit vectors.
        """
        r = self.resolution
        s = (np.arange(r, dtype=np.float64) + 0.5) / r * 2.0 - 1.0  # -1..1 across the image
        yy = self.center[0] + s[None, :] * self.half_extent  # columns -> +y
        zz = self.center[1] - s[:, None] * self.half_extent  # rows -> -z
        yy, zz = np.broadcast_arrays(yy, zz)
        n = r * r
        if self.kind == "orthographic":
            origins = np.stack([np.full(n, self.eye_x), yy.ravel(), zz.ravel()], axis=1)
            dirs = np.tile([-1.0, 0.0, 0.0], (n, 1))
        else:
            eye = np.array([self.eye_x, self.center[0], self.center[1]])
            target = np.stack([np.full(n, self.depth_x), yy.ravel(), zz.ravel()], axis=1)
            dirs = target - eye
            dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
            origins = np.broadcast_to(eye, (n, 3))
        return origins.astype(np.float32), dirs.astype(np.float32)


def fit_camera(
    subject: Subject,
    resolution: int,
    *,
    margin: float = 0.05,
    kind: str = "orthographic",
    fov_deg: float = 20.0,
    framing: str = "full",
) -> Camera:
    """Fit a camera so the subject's bounding box fills the square image with a margin.

    With a ``framing`` other than "full" (:data:`FRAMINGS`) the square shows only the top part of the subject:
    the top keeps its margin, the image's side is that part's height plus the margin, and the rest of the
    subject is cut by the bottom (and, where wider, the side) borders.

    Args:
        subject: what to frame (its ``bounds()``, metres).
        resolution: image size R ≥ 1.
        margin: free border as a fraction of the image side on each side (0 ≤ margin < 0.5).
        kind: "orthographic" (default) or "perspective".
        fov_deg: full field of view of a perspective camera, degrees.
        framing: "full", "knees-up", "waist-up", "head-shoulders" or "face".
    """
    if framing not in FRAMINGS:
        raise RelightError(f"framing {framing!r}: expected one of {list(FRAMINGS)}")
    if kind not in KINDS:
        raise RelightError(f"camera kind {kind!r}: expected one of {KINDS}")
    if int(resolution) < 1:
        raise RelightError(f"resolution: expected a positive size, got {resolution}")
    if not 0.0 <= margin < 0.5:
        raise RelightError(f"margin: expected 0 <= margin < 0.5, got {margin}")
    lo, hi = (np.asarray(b, dtype=np.float64) for b in subject.bounds())
    center = 0.5 * (lo + hi)
    half = 0.5 * float(max(hi[1] - lo[1], hi[2] - lo[2], 1e-6)) / (1.0 - 2.0 * margin)
    if framing != "full":  # the top `visible` metres, the top margin kept, the rest below the bottom border
        visible = FRAMINGS[framing] * float(max(hi[2] - lo[2], 1e-6))
        side = visible / (1.0 - margin)
        half = 0.5 * side
        center = center.copy()
        center[2] = float(hi[2]) + margin * side - half
    depth = float(hi[0] - lo[0])
    if kind == "orthographic":
        eye_x = float(hi[0] + 1.0 + depth)
    else:
        if not 1.0 <= fov_deg <= 120.0:
            raise RelightError(f"fov_deg: expected 1..120 degrees, got {fov_deg}")
        # the box's near face (depth/2 in front of the centre plane) must fit too:
        # tan(fov/2) * (D - depth/2) = half at distance D of the eye from the centre plane
        tan = math.tan(math.radians(fov_deg) / 2.0)
        dist = half / tan + 0.5 * depth
        eye_x = float(center[0] + dist)
        half = dist * tan
    return Camera(
        kind=kind,
        resolution=int(resolution),
        center=(float(center[1]), float(center[2])),
        half_extent=half,
        eye_x=eye_x,
        depth_x=float(center[0]),
    )
