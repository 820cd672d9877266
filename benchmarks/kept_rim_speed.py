"""The kept background's rim's cost on one photo: this checkout's against ``--base``'s, alternated in one process.

    PYTHONPATH=$PWD python benchmarks/kept_rim_speed.py [PHOTO] [--repeats 15] [--base a4e605c] [--models DIR]

Default photo: the reference photo in ../shared/reference (2.5 megapixels), decomposed once with the automatic matte
(the rim applies there only: ``Composer.shown_rim``). Main's form is ``--base``'s own modules, read with ``git show``
from this checkout's history and run in this process beside this checkout's (``relight/kept_rim.py``,
``image/fibres.py``, ``image/blur.py`` and ``relight/compose.py``'s ``skin_map``; each old module's names that come
from another of them wired to the old one). What each form does once per Decomposition (``Composer.kept_rim``:
the skin map and ``kept_rim``) and per light (``with_kept_rim`` on the relit colour the composite hands it, caught
under the white side lamps LEFT and RIGHT of benchmarks/real_photos.py) is timed, the two forms in turn, after one
warm-up call each; printed: best and median milliseconds of ``--repeats``, and how the forms' rims and relit colours
differ (the ``KeptRim`` arrays, and the largest change of a relit pixel in 8-bit sRGB levels).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
import types
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from _shared import missing, shared_path  # noqa: E402

import relight_rt  # noqa: E402
from relight_rt import RuntimeConfig  # noqa: E402
from relight_rt.image.io import read_image  # noqa: E402
from relight_rt.relight import compose, kept_rim  # noqa: E402

# the modules the rim's path runs, as (module name, file): loaded from --base in this order (a later one's names
# taken from an earlier one's are re-pointed to the earlier one's old form)
MODULES = (("relight_rt.image.blur", "relight_rt/image/blur.py"),
           ("relight_rt.image.fibres", "relight_rt/image/fibres.py"),
           ("relight_rt.relight.kept_rim", "relight_rt/relight/kept_rim.py"),
           ("relight_rt.relight.compose", "relight_rt/relight/compose.py"))


def base_modules(base: str) -> dict[str, types.ModuleType]:
    """``MODULES`` as they are at ``base`` (git show), each a new module object in its package (its relative imports
    resolve to this checkout's modules, then re-pointed to the old ones loaded before it)."""
    old: dict[str, types.ModuleType] = {}
    for name, path in MODULES:
        source = subprocess.run(["git", "show", f"{base}:{path}"], cwd=REPO, check=True, capture_output=True,
                                text=True).stdout
        module = types.ModuleType(name + "_base")
        module.__package__ = name.rpartition(".")[0]
        module.__file__ = f"{base}:{path}"
        exec(compile(source, module.__file__, "exec"), module.__dict__)  # noqa: S102 (this repository's own file)
        for earlier, before in old.items():
            current = sys.modules[earlier]
            for key, value in list(module.__dict__.items()):
                if not key.startswith("__") and getattr(current, key, None) is value and hasattr(before, key):
                    setattr(module, key, getattr(before, key))
        old[name] = module
    return old


def caught_colours(r, dec, light_list) -> list[np.ndarray]:
    """The relit colours ``compose`` hands ``with_kept_rim`` under each light (copies, before the rim)."""
    caught = []
    real = compose.with_kept_rim

    def catch(colour, kept, copy=True):
        caught.append(np.array(colour, np.float32))
        return real(colour, kept, copy=copy)

    compose.with_kept_rim = catch
    try:
        for light in light_list:
            r.relight(dec, light)
    finally:
        compose.with_kept_rim = real
    if len(caught) != len(light_list):
        raise SystemExit("the composite applied no kept rim (not the automatic matte over the photo's background?)")
    return caught


def levels(a: np.ndarray, b: np.ndarray) -> int:
    """The largest difference of two sRGB float images in 8-bit levels (as written: rounded, clipped)."""
    q = lambda x: np.clip(np.round(np.asarray(x, np.float64) * 255), 0, 255).astype(np.int16)  # noqa: E731
    return int(np.abs(q(a) - q(b)).max())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("photo", nargs="?", default=str(shared_path("reference", "photo", "sample.jpg")))
    p.add_argument("--repeats", type=int, default=15)
    p.add_argument("--base", default="a4e605c", help="the git revision whose modules are main's form")
    p.add_argument("--models", default=None)
    args = p.parse_args()
    if not Path(args.photo).is_file():
        raise SystemExit(missing(Path(args.photo)))

    from real_photos import LEFT, RIGHT

    r = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    image = read_image(args.photo)
    dec = r.decompose(image)
    fg, behind = dec.foreground
    crop = dec.geometry.crop(dec.image)
    colours = caught_colours(r, dec, [LEFT, RIGHT])
    old = base_modules(args.base)
    forms = {
        "base": (old["relight_rt.relight.kept_rim"], old["relight_rt.relight.compose"].skin_map),
        "this": (kept_rim, compose.skin_map),
    }

    def once(form):
        module, skin_map = forms[form]
        return module.kept_rim(behind, dec.edge, fg, None, crop, skin_map(dec))

    rims = {form: once(form) for form in forms}
    out = {form: [forms[form][0].with_kept_rim(c, rims[form]) for c in colours] for form in forms}
    a, b = rims["base"], rims["this"]
    same = a.index.shape == b.index.shape and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    print(f"{args.photo}: {image.shape[1]} x {image.shape[0]}, crop box {crop.shape[1]} x {crop.shape[0]}, rim pixels "
          f"{a.index.size} (base) / {b.index.size} (this); KeptRim identical: {same}")
    for name, x, y, c in zip(("LEFT", "RIGHT"), out["base"], out["this"], colours, strict=True):
        print(f"  {name}: relit crop box, largest change {np.abs(x - y).max():.2e} ({levels(x, y)} levels); "
              f"the rim's own change {levels(c, x)} levels at most")

    times = {(form, what): [] for form in forms for what in ("once", "LEFT", "RIGHT")}
    for _ in range(args.repeats + 1):  # the first round warms
        for form in forms:
            module, _ = forms[form]
            t = time.perf_counter()
            rim = once(form)
            times[form, "once"].append(time.perf_counter() - t)
            for name, c in zip(("LEFT", "RIGHT"), colours, strict=True):
                own = c.copy()  # as the composite: the relit colour, its own, written into
                t = time.perf_counter()
                module.with_kept_rim(own, rim, copy=False)
                times[form, name].append(time.perf_counter() - t)
    best = {}
    for (form, what), t in times.items():
        t = [1000 * x for x in t[1:]]
        best[form, what] = min(t)
        print(f"{form} {what:5s}: best {min(t):6.2f} ms, median {statistics.median(t):6.2f} ms")
    for form in forms:
        light = max(best[form, "LEFT"], best[form, "RIGHT"])
        print(f"{form}: once + a light (the slower side's best) {best[form, 'once'] + light:.2f} ms")


if __name__ == "__main__":
    main()
