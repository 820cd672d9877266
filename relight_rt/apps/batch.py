"""The one-file work of ``relight-rt relight``, shared by the single-process CLI and the Ray actors.

Both paths plan the same (input, output) pairs with :func:`plan` and run each pair through
:func:`relight_file`, so a folder relit on a Ray cluster gives the same files, byte for byte, and the
same failures as ``relight-rt relight`` on one machine.

Planning a folder leaves out the project's own files: relit results (``*_relit.png``), masks
(``*_mask.*``) and hidden files (``.*``: the atomic writer's temporary files among them), so an output
folder that is also the input folder is not relit again. Files named on the command line are taken as
given.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..engine.errors import RelightError
from ..engine.process import give_back_freed_memory
from ..image.io import IMAGE_SUFFIXES, list_images, write_image
from ..person.masks import find_mask_file

RELIT_SUFFIX = "_relit"


def is_own_file(path: Path) -> bool:
    """True for files this project writes beside photos: ``*_relit.*``, ``*_mask.*`` and hidden ``.*`` files."""
    return path.name.startswith(".") or path.stem.endswith(RELIT_SUFFIX) or path.stem.endswith("_mask")


def list_inputs(folder: str | os.PathLike) -> list[Path]:
    """The photos of a folder (sorted), without the project's own files (see :func:`is_own_file`)."""
    return [p for p in list_images(folder) if not is_own_file(p)]


def gather_inputs(inputs: Iterable[str]) -> tuple[list[Path], list[tuple[str, str]]]:
    """Image files from files and folders → (files, failures); a failure is (input, message)."""
    files, failures = [], []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            found = list_inputs(path)
            if not found:
                failures.append((item, f"folder {item} holds no images ({', '.join(IMAGE_SUFFIXES)})"))
            files.extend(found)
        elif path.is_file():
            files.append(path)
        elif path.exists():  # a FIFO or a device: reading it would block or never end
            failures.append((item, f"input {item}: not a regular file or folder"))
        else:
            failures.append((item, f"input {item} not found"))
    return files, failures


@dataclass
class Plan:
    """What ``relight-rt relight INPUTS -o OUTPUT`` will do.

    Attributes:
        inputs: every image file found, in input order (the inputs to protect).
        pairs: (input, output) per photo to relight, in input order.
        failures: (input, message) found while planning: missing inputs, empty folders, two inputs
            that would write the same output (the later one fails).
        single: one file named on the command line (``--mask FILE`` allowed).
        to_file: ``OUTPUT`` is the output file itself (single input, image suffix), not a folder.
    """

    inputs: list[Path] = field(default_factory=list)
    pairs: list[tuple[Path, Path]] = field(default_factory=list)
    failures: list[tuple[str, str]] = field(default_factory=list)
    single: bool = False
    to_file: bool = False


def plan(inputs: list[str], output: str | os.PathLike) -> Plan:
    """Plan the (input, output) pairs: NAME.ext → OUTPUT/NAME_relit.png, or OUTPUT itself for one file.

    Raises:
        RelightError: one input file and an output with an unknown image suffix.
    """
    files, failures = gather_inputs(inputs)
    out = Path(output)
    single = len(files) == 1 and len(inputs) == 1 and not Path(inputs[0]).is_dir()
    to_file = single and out.suffix.lower() in IMAGE_SUFFIXES
    if single and not to_file and out.suffix:
        raise RelightError(f"output {out}: unknown image type {out.suffix!r}; use one of {', '.join(IMAGE_SUFFIXES)}")
    result = Plan(inputs=files, failures=failures, single=single, to_file=to_file)
    taken: set[Path] = set()
    for path in files:
        target = out if to_file else out / f"{path.stem}{RELIT_SUFFIX}.png"
        key = target.resolve()
        if key in taken:
            result.failures.append((str(path), f"two inputs named {path.stem} would both write {target}"))
            continue
        taken.add(key)
        result.pairs.append((path, target))
    return result


def mask_for(image: Path, mask_arg: str | None, single: bool):
    """The mask of ``image`` as the CLI finds it (relight_rt.person.masks.find_mask_file): ``--mask`` (a file for one
    input, a folder of NAME_mask.png, or "auto"), else NAME_mask.png beside it, else None (alpha, then the
    automatic matte).

    Raises:
        RelightError: the mask folder lacks this image's mask; a mask file given for several inputs.
    """
    return find_mask_file(image, mask_arg, single=single)


def relight_file(
    relighter,
    src: Path,
    target: Path,
    light: np.ndarray,
    *,
    mask_arg: str | None = None,
    single: bool = False,
    background="original",
    protect: Iterable[str | os.PathLike] = (),
    exposure="auto",
) -> Path:
    """Relight one photo and write it atomically: the one-file work of ``relight-rt relight``.

    Args:
        relighter: a ``relight_rt.Relighter``.
        src, target: the photo and its output file (see :func:`plan`).
        light: the resolved (9, 3) RGB SH light.
        mask_arg, single: ``--mask`` and whether one file was named (see :func:`mask_for`).
        background: a relight_rt.image.compositing.Background or its shorthand ("original", "transparent", ...).
        protect: inputs the output must never replace.
        exposure: "auto", an EV offset or "physical" (relight_rt.light.exposure).

    Raises:
        RelightError, OSError: a bad photo or mask, an output that would replace an input, a failed write.
    """
    mask = mask_for(src, mask_arg, single)
    image = relighter.relight(src, light, mask=mask, background=background, exposure=exposure)
    give_back_freed_memory()  # what the relight let go, before the encoding's full-size temporaries
    return write_image(target, image, protect=protect)
