"""The kept rim's cost in the studio's live preview: the page's draw time with it against main's page without it.

    PYTHONPATH=$PWD python benchmarks/studio_rim_draw.py [--photos reference,p286] [--frames 60] [--base main]

Each photo (the reference photo, or a people_masks photo, copied alone to a temporary folder so that the studio
mattes it itself, as ``studio_preview_gap.py --band`` does) is served by the studio (bundled models, CPU, the
photo's own background, a 1-megapixel preview at most) and opened in headless chromium (Debian's, software WebGL).
In the page, four previews draw the same decoded layers on canvases of their own: this checkout's preview.js and
``--base``'s (git show: the page's module before the rim, inlined in the timing's script), each on WebGL 2 and on
Canvas 2D. Each draws a white lamp from the image's left with a little ambient (the rim's side goes dark: its pixels
take the rim) and finishes (WebGL: one pixel read back), ``--frames`` times, the four in turn; median milliseconds
per draw, and the median of each frame's difference (the machine's load moves both of a frame's draws alike).
Printed with the rim's pixels and its bytes in the layers.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from headless_studio import chromium, serving  # noqa: E402
from studio_preview_gap import BUNDLED, band_photo  # noqa: E402

import relight_rt  # noqa: E402
from relight_rt import RuntimeConfig  # noqa: E402
from relight_rt.apps.studio.core import Studio  # noqa: E402

TIMING = """async ([light, frames]) => {
  const old = (() => { BASE; return { createPreview }; })();  // --base's module, inlined (the page's CSP allows no
  // module from a blob or eval; what Playwright evaluates is not the page's script)
  const make = (create, renderer, layers) => {
    const canvas = document.createElement("canvas");
    document.body.appendChild(canvas);
    return create(canvas, layers, { renderer });
  };
  const layers = studio.state.layers;
  const previews = {
    "webgl rim": make(studio.createPreview, "webgl", layers),
    "webgl base": make(old.createPreview, "webgl", layers),
    "canvas rim": make(studio.createPreview, "canvas", layers),
    "canvas base": make(old.createPreview, "canvas", layers),
  };
  const times = Object.fromEntries(Object.keys(previews).map((k) => [k, []]));
  for (const p of Object.values(previews)) { p.draw(light); p.finish(); }  // warm up
  for (let i = 0; i < frames; i++) {
    for (const [k, p] of Object.entries(previews)) {
      const t0 = performance.now();
      p.draw(light);
      p.finish();
      times[k].push(performance.now() - t0);
    }
  }
  return { times, kinds: Object.fromEntries(Object.entries(previews).map(([k, p]) => [k, p.kind])) };
}"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--photos", default="reference,p286")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--base", default="main", help="the git revision whose preview.js is the page without the rim")
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    args = ap.parse_args(argv)
    base = subprocess.run(["git", "show", f"{args.base}:relight_rt/apps/studio/static/preview.js"], check=True,
                          capture_output=True, text=True, cwd=REPO).stdout
    from real_photos import LEFT

    rl = relight_rt.open(RuntimeConfig(models=BUNDLED, device="cpu"))
    with tempfile.TemporaryDirectory() as tmp, chromium(args.chromium, tempfile.mkdtemp(prefix="chromium-")) as ctx:
        for name in args.photos.split(","):
            studio = Studio(band_photo(name, Path(tmp)), None, "original", rl)
            meta = studio.info()["preview"]
            light = studio.preview_light(np.asarray(LEFT, np.float32)).ravel().tolist()
            with serving(studio) as url:
                page = ctx.new_page()
                page.goto(url + "/?renderer=canvas")
                page.wait_for_selector("body[data-ready='1']", timeout=120_000)
                got = page.evaluate(TIMING.replace("BASE;", base.replace("export ", "")), [light, args.frames])
                page.close()
            med = {k: statistics.median(v) for k, v in got["times"].items()}
            paired = {kind: statistics.median(np.subtract(got["times"][f"{kind} rim"], got["times"][f"{kind} base"]))
                      for kind in ("webgl", "canvas")}
            print(f"{name}: preview {meta['width']}x{meta['height']}, rim {meta['rim_samples']} pixels "
                  f"({16 * meta['rim_samples']} bytes of {len(studio.layers_bytes())})")
            for kind in ("webgl", "canvas"):
                rim, old = med[f"{kind} rim"], med[f"{kind} base"]
                print(f"  {got['kinds'][f'{kind} rim']:9s} {old:7.2f} ms -> {rim:7.2f} ms, median of {args.frames}; "
                      f"the median of the frames' differences {paired[kind]:+.2f} ms")
            print(json.dumps({k: round(v, 3) for k, v in med.items()}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
