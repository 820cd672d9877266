"""Where a `relight` command's resident memory peaks: the process's resident set sampled every 5 ms while the command
runs in this process, and the highest value between the group's steps (matting and stage 1, each person's own colours
and the group's shown edge, the people's loop, the image's encoding).

    python benchmarks/group_photo.py --side 5000 --people 4 -o /tmp/g25.png    # 16 people, 25 MP
    PYTHONPATH=$PWD python benchmarks/group_memory.py /tmp/g25.png --person all --preset neon
    PYTHONPATH=$PWD python benchmarks/group_memory.py /tmp/g25.png --preset neon    # the largest person

Every argument after the script's name is `relight-rt relight`'s; the picture goes to a temporary folder. The resident
set read here (/proc/self/statm, Linux) counts a little more than `/usr/bin/time -v`'s maximum, which the figures in
docs/ quote.
"""

from __future__ import annotations

import functools
import resource
import sys
import tempfile
import threading
import time
from pathlib import Path

STEPS = (  # (module, owner or None, function): the marks between which the peak is read
    ("relight_rt.relight.relighter", "Relighter", "_group"),
    ("relight_rt.relight.people", None, "with_shown_edge"),
    ("relight_rt.relight.people", None, "by_person_lights"),
    ("relight_rt.relight.relighter", "Relighter", "_relight"),
    ("relight_rt.image.io", None, "encode_image"),
)


def _resident() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize()


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help"):
        print(__doc__)
        return 0
    import importlib

    from relight_rt.cli import main as cli

    samples: list[tuple[float, int]] = []
    marks: list[tuple[float, str]] = []
    done = threading.Event()

    def sample() -> None:
        while not done.is_set():
            samples.append((time.perf_counter(), _resident()))
            time.sleep(0.005)

    def marked(f, name):
        @functools.wraps(f)
        def call(*a, **k):
            marks.append((time.perf_counter(), "> " + name))
            try:
                return f(*a, **k)
            finally:
                marks.append((time.perf_counter(), "< " + name))
        return call

    for module, owner, name in STEPS:
        where = importlib.import_module(module)
        where = getattr(where, owner) if owner else where
        setattr(where, name, marked(getattr(where, name), name))
    thread = threading.Thread(target=sample, daemon=True)
    start = time.perf_counter()
    thread.start()
    with tempfile.TemporaryDirectory() as tmp:
        code = cli(["relight", *args, "-o", str(Path(tmp) / "out.png"), "-q"])
    marks.append((time.perf_counter(), "end"))
    done.set()
    thread.join()
    print(f"exit {code}; peak {max(r for _, r in samples) / 1e6:.0f} MB (ru_maxrss "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3:.0f} MB)")
    print(f"{'s':>7}  {'mark':24} {'MB now':>7} {'MB peak since the mark before':>30}")
    before = start
    for at, name in marks:
        now = min(samples, key=lambda s: abs(s[0] - at))[1]
        peak = max((r for t, r in samples if before <= t <= at), default=now)
        print(f"{at - start:7.2f}  {name:24} {now / 1e6:7.0f} {peak / 1e6:30.0f}")
        before = at
    return code


if __name__ == "__main__":
    raise SystemExit(main())
