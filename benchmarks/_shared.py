"""Where ../shared is (the reference data, realdata and hdri beside the checkout), from any checkout.

The benchmark scripts import this instead of counting parents: ``REPO.parent / "shared"`` holds only beside the
main checkout or a clone (/work/main -> /work/shared), ``REPO.parent.parent`` only beside a git worktree
(/work/wt/X -> /work/shared). ``shared_dir`` walks every folder above the checkout, as tests/conftest.py's
``_find_shared`` does, and honours the same override, ``RELIGHT_RT_SHARED``.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ENV = "RELIGHT_RT_SHARED"


def shared_dir(*parts: str) -> Path | None:
    """The shared/ folder that holds ``parts`` (``shared_dir("realdata", "yale")``), or None.

    ``$RELIGHT_RT_SHARED`` when it is set (and then only it); else the nearest ``shared/`` beside the checkout or
    beside any folder above it that holds ``parts``.
    """
    env = os.environ.get(ENV)
    if env:
        return Path(env) if Path(env, *parts).exists() else None
    for parent in REPO.parents:
        candidate = parent / "shared"
        if candidate.joinpath(*parts).exists():
            return candidate
    return None


def shared_path(*parts: str) -> Path:
    """``parts`` inside the shared folder that holds them; where none does, the path they would have beside the
    checkout (or under ``$RELIGHT_RT_SHARED``), which does not exist: a default that the script reports missing."""
    found = shared_dir(*parts)
    if found is None:
        env = os.environ.get(ENV)
        found = Path(env) if env else REPO.parent / "shared"
    return found.joinpath(*parts)


def missing(path: Path) -> str:
    """What to say when ``path`` (a shared set a script reads) is absent."""
    return (f"{path} not found (give its path, set {ENV} to the shared folder, or put shared/ beside the checkout "
            "or a folder above it)")


def warn_missing(path: Path, what: str) -> None:
    """One loud line on stderr: ``what`` (the part of the measurement that ``path`` feeds) is left out."""
    print(f"WARNING: {missing(path)}; {what} left out", file=sys.stderr, flush=True)


def photo_arguments(parser, repeats: int) -> None:
    """The reference photo and its mask (positional, defaulting to ../shared/reference/photo), ``--repeats`` and
    ``--models``: the arguments of the scripts that time one photo's relight."""
    photo = shared_path("reference", "photo")
    parser.add_argument("photo", nargs="?", default=str(photo / "sample.jpg"))
    parser.add_argument("mask", nargs="?", default=str(photo / "sample_mask.png"))
    parser.add_argument("--repeats", type=int, default=repeats)
    parser.add_argument("--models", default=None)


def opened_photo(args):
    """(runtime, image, mask) for ``photo_arguments``' ``args``; exits with ``missing`` where a file is absent."""
    for path in (Path(args.photo), Path(args.mask)):
        if not path.is_file():
            raise SystemExit(missing(path))
    import relight_rt
    from relight_rt import RuntimeConfig
    from relight_rt.image.io import read_image, read_mask

    runtime = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    image = read_image(args.photo)
    return runtime, image, read_mask(args.mask, image.shape[:2])


def timed(fn, repeats: int) -> tuple[float, float]:
    """Best and median milliseconds of ``repeats`` calls of ``fn`` after one call to warm it."""
    fn()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return 1000 * min(times), 1000 * statistics.median(times)
