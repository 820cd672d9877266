"""What the renderer draws: a subject made of textured triangle-mesh parts.

Frame (DESIGN.md §3): +x points from the subject toward the camera, +y toward the image's right,
+z up, right-handed; lengths in metres. The camera looks along −x.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Part:
    """One textured mesh of a subject (the body, a garment shell, hair, shoes, a scan).

    Attributes:
        name: what it is ("body", "shirt", "hair", ...), for logs and previews.
        vertices: (V, 3) float32 positions in the subject frame, metres.
        faces: (F, 3) int32 vertex indices, counter-clockwise seen from outside.
        uv: (F, 3, 2) float32 texture coordinates per face corner, in [0, 1], v pointing up
            (row 0 of a texture is v = 1).
        albedo: (Ht, Wt, 3) float32 texture in [0, 1], RGB, in the value space written to
            ``NAME_tex.png`` (no gamma is applied anywhere in the pipeline), or a (3,) colour.
        skin: (Ht, Wt) float32 texture in [0, 1] (1 = exposed skin), or a scalar for the whole part.
        roughness: microfacet roughness (GGX alpha) for the non-diffuse "photo" renders: a scalar or
            an (Ht, Wt) texture.
        specular: strength of the specular lobe, 0 = purely diffuse: a scalar or an (Ht, Wt) texture.
        subsurface: 0..1, how much soft subsurface look the photo renderer adds (skin ~ 1).
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    albedo: np.ndarray
    skin: np.ndarray | float = 0.0
    roughness: np.ndarray | float = 0.6
    specular: np.ndarray | float = 0.0
    subsurface: float = 0.0


@dataclass
class Subject:
    """A person (or any object) to render: its parts, drawn and ray-cast together."""

    parts: list[Part] = field(default_factory=list)
    name: str = "subject"

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) corners of the axis-aligned box around every part, each (3,)."""
        pts = np.concatenate([p.vertices for p in self.parts], axis=0)
        return pts.min(axis=0), pts.max(axis=0)
