"""relight_rt's ComfyUI nodes: a custom node package (docs/COMFYUI.md says how to install it).

ComfyUI imports this folder as a package (a link to it in ComfyUI's ``custom_nodes/``) and reads the two
mappings below. relight_rt itself comes from ComfyUI's Python environment when installed there
(``pip install relight-rt`` or ``pip install -e`` of a checkout), else from the checkout this folder sits in.
"""

import importlib.util
import sys
from pathlib import Path

if importlib.util.find_spec("relight_rt") is None:  # not installed: the checkout around this folder
    sys.path.append(str(Path(__file__).resolve().parent.parent))

from .nodes import DISPLAY_NAMES, NODES  # noqa: E402

NODE_CLASS_MAPPINGS = NODES
NODE_DISPLAY_NAME_MAPPINGS = DISPLAY_NAMES

__all__ = ["NODE_CLASS_MAPPINGS", "NODE_DISPLAY_NAME_MAPPINGS"]
