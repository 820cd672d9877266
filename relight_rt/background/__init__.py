"""Deprecated name of :mod:`relight_rt.scene_light` (light from a background photo); kept for one release.

``import relight_rt.background`` warns once and gives the very module ``relight_rt.scene_light`` (the same
object, so setting one of its numbers reaches the code that reads it). This is a package directory, not a
``background.py``, so that the file's history follows the rename to ``scene_light.py``.
"""

import sys
import warnings

from .. import scene_light as _scene_light

warnings.warn("relight_rt.background is renamed relight_rt.scene_light; the old name goes in the next release",
              DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _scene_light
