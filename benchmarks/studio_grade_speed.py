"""How long the studio's preview takes to find the background's grade (sh.js ``backgroundGrade``) a frame.

    PYTHONPATH=$PWD python benchmarks/studio_grade_speed.py [--calls 40] [--chromium /usr/bin/chromium]

The bundled street photo (a backdrop to grade, the automatic matte) served by the studio's own server to headless
chromium (benchmarks/headless_studio.py); per preset (night, campfire, window-left) the page's ``previewGrade`` on
the light it shows, timed ``--calls`` times with ``performance.now()`` after one call: best and median ms.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from headless_studio import chromium, serving

# isort: split
import relight_rt
from relight_rt import RuntimeConfig, lights
from relight_rt.apps.studio.core import Studio

REPO = Path(__file__).resolve().parents[1]
TIMED = """([L, calls]) => {
  const s = studio.state;
  s.lamp.on = false; s.ambient = 0; s.base.light = L;
  document.getElementById('grade-background').checked = true;
  const light = studio.previewLight(studio.composedLight());
  studio.previewGrade(light);
  const t = [];
  for (let i = 0; i < calls; i++) {
    const a = performance.now();
    studio.previewGrade(light);
    t.push(performance.now() - a);
  }
  t.sort((a, b) => a - b);
  return [t[0], t[Math.floor(calls / 2)]];
}"""


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--calls", type=int, default=40)
    p.add_argument("--chromium", default="/usr/bin/chromium")
    args = p.parse_args()
    models = Path(relight_rt.__file__).resolve().parent / "models"
    studio = Studio(str(REPO / "relight_rt" / "data" / "example_scene.jpg"), None, "original",
                    relight_rt.open(RuntimeConfig(models=models, device="cpu")))
    print(f"grade sample: {studio.info()['preview']['grade_samples']} pixels")
    with serving(studio) as url, chromium(args.chromium, tempfile.mkdtemp(prefix="grade-speed-")) as context:
        page = context.new_page()
        page.goto(url)
        page.wait_for_selector("body[data-ready='1']", timeout=30_000)
        for name in ("night", "campfire", "window-left"):
            light = lights.preset(name).astype("float32").ravel().tolist()
            best, median = page.evaluate(TIMED, [light, args.calls])
            print(f"{name}: previewGrade best {best:.2f} ms, median {median:.2f} ms", flush=True)


if __name__ == "__main__":
    main()
