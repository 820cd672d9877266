"""Video frames over their own background with the automatic matte keep the background's rim (videorim44, issue 48).

    PYTHONPATH=$PWD python benchmarks/video_rim.py [--clips clip,reference] [--lights LEFT,RIGHT,campfire]
        [--frames N] [--save DIR] [--out F.json]
    PYTHONPATH=$PWD python benchmarks/video_rim.py --speed [--rounds 3] [--edge-arms]
    PYTHONPATH=$PWD python benchmarks/video_rim.py --edge off|on ...   (compose.FRAME_EDGE for the run; default on)
    PYTHONPATH=$PWD python benchmarks/video_rim.py --given F.json [--code /work/main]

Clips (read in place): ``realdata/people_masks/clip`` (854x480) and ``reference/video`` (720x940). Each frame's
automatic matte (``VideoMatter``, as ``relight-rt video`` makes it for frames without a mask) is found once; then the
clip is relit as ``relight-rt video`` does by default (the stabiliser at 0.8, exposure auto for the light, the original
background, batches of 4) twice: with the rim (the frames marked automatic, this checkout's path) and without (the
same mattes handed over as given masks: no rim, main's path for every frame). The rim on video frames is
``relight.compose.FRAME_RIM`` (on since videorim44's merge); this script sets it for each arm. Per clip and light:

- ``dark``: ``benchmarks/dark_edge.py``'s ``measure`` per frame (the frame, its matte, the relit frame), the share of
  the edge band turned dark against the background beside it, mean over the frames;
- ``flicker``: on the pixels within ``BAND`` px of frame t's matte's 0.5 outline (either side), mean |relit_t -
  relit_(t-1)| in 8-bit levels over the channels, less the same of the input frames, mean (and 95th percentile) over
  the consecutive pairs.

``--speed``: the relighting part of a frame (decompose, stabiliser, render under LEFT) on the reference's frames with
their automatic mattes, rim on and off alternated batch by batch (order swapped each batch, one stabiliser per arm):
median of the paired ratios on / off; ``--edge-arms``: the arms are the frames' shown edge on / off instead
(``relight.compose.FRAME_EDGE``, videoedge44), the rim on in both. ``--given F.json``: the SHA-256 of every relit
frame of both clips with their given (hand) masks under the three lights, through ``relight_frames`` with the frames
as ``FrameSource`` reads them;
``--code DIR`` imports relight_rt from DIR (another checkout, e.g. main) so that the two files can be compared.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path


def _code_first(argv) -> None:
    """``--code DIR``: relight_rt imported from DIR before the benchmark helpers put this checkout first."""
    if argv is None:
        argv = sys.argv[1:]
    if "--code" in argv:
        sys.path.insert(0, str(Path(argv[argv.index("--code") + 1]).resolve()))
        import relight_rt  # noqa: F401  (cached: the helpers' ``import relight_rt`` gets this one)


_code_first(None)

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from _shared import shared_path  # noqa: E402
from real_photos import LEFT, RIGHT  # noqa: E402

import relight_rt  # noqa: E402
from relight_rt import RuntimeConfig  # noqa: E402

BAND = 6  # px either side of the matte's 0.5 outline: the band whose frame-to-frame change is measured
CLIPS = {"clip": ("realdata", "people_masks", "clip"), "reference": ("reference", "video")}
LIGHTS = {"LEFT": LEFT, "RIGHT": RIGHT}


def light_of(name: str):
    return LIGHTS.get(name, name)


def engine_for(relighter, name: str):
    """The engine ``relight_clip`` builds for one light (exposure auto, as the light's preset asks)."""
    from relight_rt.light.exposure import for_light
    from relight_rt.light.spec import LightSpec
    from relight_rt.video.job import RelighterEngine

    return RelighterEngine(relighter, exposure=for_light("auto", LightSpec.of(light_of(name))))


def matted_frames(path: Path, matter, limit: int | None) -> list:
    """The clip's frames with their automatic mattes (``FrameSource(masks="auto")``), images kept as 8 bits."""
    from relight_rt.video.frames import FrameSource

    out = []
    for f in FrameSource(path, "auto", matter=matter):
        out.append((f.index, f.name, np.round(f.image * 255).astype(np.uint8), f.mask))
        if limit and len(out) >= limit:
            break
    return out


def relit(frames: list, relighter, name: str, automatic: bool):
    """Yields (frame, relit) for the clip relit under light ``name`` as ``relight-rt video`` does by default."""
    from relight_rt.video.frames import Frame
    from relight_rt.video.job import LightSchedule, relight_frames
    from relight_rt.video.stabilize import Stabilizer

    light = relighter.resolve_light(light_of(name), dtype=np.float64)
    source = (Frame(i, n, img.astype(np.float32) / 255, m, automatic) for i, n, img, m in frames)
    for f, out, _ in relight_frames(source, LightSchedule.constant(light), fps=25.0, engine=engine_for(relighter, name),
                                    stabilizer=Stabilizer(0.8), batch_size=4):
        yield f, out


def band_of(alpha: np.ndarray) -> np.ndarray:
    """Pixels within ``BAND`` px of the matte's 0.5 outline, either side."""
    inside = (alpha >= 0.5).astype(np.uint8)
    d_in = cv2.distanceTransform(np.pad(inside, 1, constant_values=1), cv2.DIST_L2, 3)[1:-1, 1:-1]
    d_out = cv2.distanceTransform(1 - inside, cv2.DIST_L2, 3)
    return np.where(inside > 0, d_in <= BAND, d_out <= BAND)


def figures(frames: list, relighter, name: str, automatic: bool, save: Path | None, tag: str) -> dict:
    from dark_edge import measure

    dark, steps = [], []
    prev = None
    for f, out in relit(frames, relighter, name, automatic):
        out = np.clip(np.asarray(out[..., :3], np.float32), 0, 1)
        dark.append(measure(f.image, f.mask, out)["dark_edge"])
        if prev is not None:
            band = band_of(f.mask)
            if band.any():
                d_out = np.abs(out[band] - prev[1][band]).mean() * 255
                d_in = np.abs(f.image[band] - prev[0][band]).mean() * 255
                steps.append(float(d_out - d_in))
        prev = (f.image, out)
        if save is not None and f.index % 10 == 0:
            bgr = cv2.cvtColor(np.round(out * 255).astype(np.uint8), cv2.COLOR_RGB2BGR)
            cv2.imwrite(str(save / f"{tag}_{name}_{'rim' if automatic else 'none'}_{f.name}.png"), bgr)
    return {"dark": float(np.mean(dark)), "flicker": float(np.mean(steps)),
            "flicker_p95": float(np.percentile(steps, 95)), "dark_frames": dark, "steps": steps}


def speed(relighter, matter, rounds: int, edge_arms: bool = False) -> None:
    from relight_rt.relight import compose
    from relight_rt.video.stabilize import Stabilizer

    frames = matted_frames(shared_path(*CLIPS["reference"]), matter, None)
    engine = engine_for(relighter, "LEFT")
    light = relighter.resolve_light(LEFT)
    ratios, times = [], {True: [], False: []}
    for r in range(rounds):
        stab = {True: Stabilizer(0.8), False: Stabilizer(0.8)}
        for b in range(0, len(frames), 4):
            batch = frames[b : b + 4]
            imgs = [img.astype(np.float32) / 255 for _, _, img, _ in batch]
            masks = [m for *_, m in batch]
            took = {}
            for arm in ((True, False) if (b // 4 + r) % 2 == 0 else (False, True)):
                if edge_arms:
                    compose.FRAME_EDGE = arm
                t0 = time.perf_counter()
                for lay in engine.decompose(imgs, masks, [arm or edge_arms] * len(imgs)):
                    albedo, transport = stab[arm].update(lay.image, lay.mask, lay.albedo, lay.transport)
                    own = stab[arm].smooth_light(lay.light)
                    engine.render(lay, albedo, transport, own, light, relight_rt.Background.original())
                took[arm] = (time.perf_counter() - t0) / len(imgs)
                times[arm].append(took[arm])
            if r or b:  # the first batch warms both up
                ratios.append(took[True] / took[False])
    q = np.percentile(ratios, [25, 50, 75])
    what = "shown edge" if edge_arms else "rim"
    print(f"relighting a 720x940 frame, {what} on / off: median {np.median(times[True]) * 1e3:.1f} / "
          f"{np.median(times[False]) * 1e3:.1f} ms; paired ratio median {q[1]:.3f} ({q[0]:.3f}-{q[2]:.3f}), "
          f"{len(ratios)} pairs")


def given(relighter, out: Path, lights: list[str]) -> None:
    """SHA-256 of every frame relit with the clips' given masks (``FrameSource``'s STEM_mask files)."""
    from relight_rt.video.frames import FrameSource
    from relight_rt.video.job import LightSchedule, RelighterEngine, relight_frames  # noqa: F401
    from relight_rt.video.stabilize import Stabilizer

    digests = {}
    for clip, parts in CLIPS.items():
        for name in lights:
            light = relighter.resolve_light(light_of(name), dtype=np.float64)
            for f, img, _ in relight_frames(FrameSource(shared_path(*parts)), LightSchedule.constant(light),
                                            engine=engine_for(relighter, name), stabilizer=Stabilizer(0.8),
                                            batch_size=4):
                digests[f"{clip}/{name}/{f.name}"] = hashlib.sha256(np.ascontiguousarray(img).tobytes()).hexdigest()
            print(clip, name, len(digests), flush=True)
    out.write_text(json.dumps({"relight_rt": relight_rt.__file__, "digests": digests}, indent=0))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--clips", default="clip,reference")
    p.add_argument("--lights", default="LEFT,RIGHT,campfire")
    p.add_argument("--frames", type=int, default=None, help="at most this many frames of each clip")
    p.add_argument("--save", type=Path, default=None, help="every 10th relit frame as PNG here (not the repository)")
    p.add_argument("--out", type=Path, default=None, help="a JSON file for the per-frame figures")
    p.add_argument("--speed", action="store_true")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--edge-arms", action="store_true", help="--speed: the shown edge on / off, the rim on in both")
    p.add_argument("--edge", choices=("on", "off"), default="on", help="compose.FRAME_EDGE for the run")
    p.add_argument("--given", type=Path, default=None, help="write the given-mask frames' digests to this JSON")
    p.add_argument("--code", type=Path, default=None, help="import relight_rt from this checkout (read first)")
    args = p.parse_args(argv)
    print(f"relight_rt from {relight_rt.__file__}", file=sys.stderr)
    config = RuntimeConfig(device="cpu")
    relighter = relight_rt.open(config)
    if args.given:
        given(relighter, args.given, args.lights.split(","))
        return 0
    from relight_rt.builder import video_matter
    from relight_rt.relight import compose

    compose.FRAME_RIM = True  # (the shipped setting) the rim arm; the other marks no frame automatic
    if hasattr(compose, "FRAME_EDGE"):  # (absent before videoedge44: --code of an older checkout)
        compose.FRAME_EDGE = args.edge == "on"
    if args.speed:
        speed(relighter, video_matter(config), args.rounds, args.edge_arms)
        return 0
    if args.save:
        args.save.mkdir(parents=True, exist_ok=True)
    results: dict = {}
    for clip in args.clips.split(","):
        t0 = time.time()
        frames = matted_frames(shared_path(*CLIPS[clip]), video_matter(config), args.frames)  # a clip's own matter
        for name in args.lights.split(","):
            res = {arm: figures(frames, relighter, name, arm == "rim", args.save, clip) for arm in ("none", "rim")}
            results[f"{clip}/{name}"] = res
            print(f"{clip} {name}: dark {res['none']['dark']:.4f} -> {res['rim']['dark']:.4f} "
                  f"({100 * (res['rim']['dark'] / max(res['none']['dark'], 1e-9) - 1):+.1f} %); flicker "
                  f"{res['none']['flicker']:+.3f} -> {res['rim']['flicker']:+.3f} levels (p95 "
                  f"{res['none']['flicker_p95']:+.3f} -> {res['rim']['flicker_p95']:+.3f})  {time.time() - t0:.0f} s",
                  flush=True)
        none = np.mean([results[f"{clip}/{n}"]["none"]["dark"] for n in args.lights.split(",")])
        rim = np.mean([results[f"{clip}/{n}"]["rim"]["dark"] for n in args.lights.split(",")])
        print(f"{clip}: dark edge over the lights {none:.4f} -> {rim:.4f} ({100 * (rim / max(none, 1e-9) - 1):+.1f} %)")
    if args.out:
        args.out.write_text(json.dumps(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
