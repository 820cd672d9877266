"""Deprecated: ``relight-rt mask`` lives in relight_rt.cli.mask (this module goes in the next release).

``read_photo`` and ``cutout`` are re-exported from there, with a DeprecationWarning at import.
"""

import warnings

from .cli.mask import cutout, read_photo

warnings.warn("relight_rt.mask_cli is deprecated; use relight_rt.cli.mask (read_photo, cutout)", DeprecationWarning,
              stacklevel=2)  # fmt: skip

__all__ = ["cutout", "read_photo"]
