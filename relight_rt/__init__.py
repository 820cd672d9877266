"""relight_rt: monocular full-body human relighting as a lean ONNX runtime.

After Tajima, Kanamori & Endo, "Relighting Humans in the Wild: Monocular Full-Body Human
Relighting with Domain Adaptation" (Pacific Graphics 2021). Conventions (SH order, frame,
colour order) are those of DESIGN.md §3: RGB, real orthonormal degree-2 SH, +x toward the camera.
"""

from ._errors import RelightError
from ._version import __version__

__all__ = [
    "RelightError",
    "__version__",
]
