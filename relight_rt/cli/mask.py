"""``relight-rt mask``: automatic person masks, to inspect, fix by hand and reuse.

Examples::

    relight-rt mask photo.jpg -o photo_mask.png          # one 8-bit PNG
    relight-rt mask photos/ -o masks/                     # NAME_mask.png per image (past bad files)
    relight-rt mask clip.mp4 -o clip_mask.avi             # a mask video (temporal smoothing)
    relight-rt mask clip.mp4 -o clip_masks/               # or one frame_NNNNNN_mask.png per frame
    relight-rt mask frames/ --sequence -o masks/          # a folder of video frames, smoothed over time
    relight-rt mask photo.jpg -o m.png --foreground cut.png   # + an RGBA cut-out, old background taken out

The masks come from relight_rt.person.matting (MediaPipe-derived graphs bundled with the package). Outputs are
written atomically and never over an input (nor over an existing file in an input folder).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from ..engine.errors import RelightError
from ..engine.files import ProtectedPaths, check_target, write_all
from ..image.io import IMAGE_SUFFIXES, image_writer, list_images, read_image, write_image
from ..video.frames import VIDEO_SUFFIXES
from .options import add_max_pixels
from .progress import Progress, progress
from .report import finish_batch

log = logging.getLogger(__name__)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``mask`` command to the ``relight-rt`` subparsers; returns its parser."""
    p = subparsers.add_parser(
        "mask",
        help="automatic person masks for photos, folders and videos",
        description="Write an automatic person mask (8-bit PNG; white = person) for each input: a PNG for one "
        "image, NAME_mask.png per image of a folder, a mask video or PNG frames for a video.",
    )
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="image files, folders of images, or one video file")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output .png (one image), folder, or video file (.avi/.mp4/.mkv; a video input)")  # fmt: skip
    p.add_argument("--person", choices=("largest", "all"), default="largest",
                   help="which people to mask: the largest and those standing with them, as tall and in full view "
                   "(default), or all: everyone at least 6%% of the "
                   "photo's height tall and in view (people overlapping one another may come as one, or the one "
                   "behind be missed)")  # fmt: skip
    p.add_argument("--no-refine", action="store_true", help="skip the guided-filter edge refinement")
    p.add_argument("--binary", action="store_true", help="write 0/255 masks (threshold 0.5) instead of soft ones")
    p.add_argument("--foreground", metavar="OUT",
                   help="also write the cut-out as RGBA PNG: the person's colour with the old background taken "
                   "out of the soft edge (decontaminated), alpha = the mask; a .png for one image, else a folder "
                   "of NAME_foreground.png")  # fmt: skip
    p.add_argument("--sequence", action="store_true",
                   help="a folder is one video's frames (as for a video file): follow the person, smooth the "
                   "outline over time, and complete as a photo a frame whose matte drops part of the person the last "
                   "frames held")  # fmt: skip
    p.add_argument("--smoothing", type=float, default=0.7,
                   help="video: weight of the motion-compensated history in [0, 1) (default 0.7; 0 = off)")  # fmt: skip
    p.add_argument("--models", metavar="DIR", help="folder with matte_pose.onnx and matte_roi.onnx (default: bundled)")
    p.add_argument("--device", choices=("auto", "cpu", "cuda"), default="cpu", help="where to run (default: cpu)")
    add_max_pixels(p)  # photos and every video frame
    p.set_defaults(func=cmd_mask)
    return p


def read_photo(path: Path) -> np.ndarray:
    """Any readable image file as float32 RGB (H, W, 3) in [0, 1] (gray and 16-bit files converted,
    alpha dropped, EXIF orientation applied)."""
    return read_image(path, "image")[..., :3]  # the runtime's one intake


def cutout(rgb: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(H, W, 4) straight RGBA: the decontaminated foreground colour (relight_rt.image.foreground) and the alpha;
    colour 0 where alpha is 0."""
    from ..image.foreground import estimate_foreground

    fg = estimate_foreground(rgb, alpha)
    fg[alpha <= 0] = 0.0
    return np.concatenate([fg, alpha[..., None]], axis=2)


def _finish(alpha: np.ndarray, binary: bool) -> np.ndarray:
    return (alpha >= 0.5).astype(np.float32) if binary else alpha


def cmd_mask(args: argparse.Namespace) -> int:
    from ..person.matting import PersonMatter, VideoMatter

    inputs = [Path(p) for p in args.inputs]
    out = Path(args.output)
    videos = [p for p in inputs if p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES]
    if videos and len(inputs) > 1:
        raise RelightError(f"{videos[0]}: a video input must be the only input")
    if args.foreground and (videos or args.sequence):
        raise RelightError("--foreground: cut-outs are written for photos, not for a video or --sequence")
    if not 0.0 <= args.smoothing < 1.0:
        raise RelightError(f"--smoothing: expected a value in [0, 1), got {args.smoothing}")
    matter = PersonMatter(args.models, device=args.device, person=args.person, refine=not args.no_refine)
    if videos or args.sequence:
        vm = VideoMatter(matter, smoothing=args.smoothing, refine=not args.no_refine)
    if videos:
        return _run_video(videos[0], out, vm, args.binary)
    if args.sequence:
        if len(inputs) != 1 or not inputs[0].is_dir():
            raise RelightError("--sequence: expected one folder of video frames")
        return _run_sequence(inputs[0], out, vm, args.binary)

    files: list[Path] = []
    failures: list[tuple[str, str]] = []
    protect: set[Path] = set()
    for item in inputs:
        if item.is_dir():
            found = list_images(item)
            if not found:
                failures.append((str(item), f"folder {item} holds no images ({', '.join(IMAGE_SUFFIXES)})"))
            files.extend(found)
            protect.update(p for p in item.iterdir() if p.is_file())  # existing masks there too
        elif item.is_file():
            files.append(item)
            protect.add(item)
        elif item.exists():  # a FIFO or a device: reading it would block or never end
            failures.append((str(item), f"input {item}: not a regular file or folder"))
        else:
            failures.append((str(item), f"input {item} not found"))
    single = len(inputs) == 1 and inputs[0].is_file()
    to_file = single and out.suffix != ""
    if to_file and out.suffix.lower() != ".png":
        raise RelightError(f"output {out}: masks are written as .png (8-bit); got {out.suffix!r}")
    fg = Path(args.foreground) if args.foreground else None
    if fg is not None and to_file and fg.suffix.lower() != ".png":
        raise RelightError(f"--foreground {fg}: one image's cut-out is written as .png (RGBA); got {fg.suffix!r}")
    if fg is not None and not to_file and fg.suffix:
        raise RelightError(f"--foreground {fg}: several inputs write NAME_foreground.png into a folder")
    if fg is not None and fg.resolve() == out.resolve():
        raise RelightError(f"--foreground {fg}: the same file as the mask output")
    if not to_file and files:
        out.mkdir(parents=True, exist_ok=True)
        if fg is not None:
            fg.mkdir(parents=True, exist_ok=True)
    written: set[Path] = set()
    protected = ProtectedPaths(protect)
    for path in progress(files, "image", len(files) > 1):
        target = out if to_file else out / f"{path.stem}_mask.png"
        cut = None if fg is None else fg if to_file else fg / f"{path.stem}_foreground.png"
        try:
            if target.resolve() in written:
                raise RelightError(f"two inputs named {path.stem} would both write {target}")
            for t in (target, cut) if cut is not None else (target,):  # before any work, and before any write
                check_target(t, protected)
            rgb = read_photo(path)
            alpha = _finish(matter(rgb, str(path)), args.binary)
            outputs = [(target, image_writer(alpha, target))]
            if cut is not None:
                outputs.append((cut, image_writer(cutout(rgb, alpha), cut)))
            write_all(outputs, protect=protected)  # the mask and its cut-out: both or neither (issue 50 bug 9)
            written.add(target.resolve())
            (log.debug if len(files) > 1 else log.info)("%s -> %s", path, target)  # a bar shows a folder
        except (RelightError, OSError) as exc:
            hint = "; if there is one, paint its mask by hand (white = person) and give it to relight with --mask"
            failures.append((str(path), str(exc) + (hint if "no person found" in str(exc) else "")))
    return finish_batch(failures, len(written), many=len(files) > 1)


def _run_sequence(folder: Path, out: Path, vm, binary: bool) -> int:
    files = list_images(folder)
    if not files:
        raise RelightError(f"folder {folder} holds no images ({', '.join(IMAGE_SUFFIXES)})")
    protect = [p for p in folder.iterdir() if p.is_file()]
    out.mkdir(parents=True, exist_ok=True)
    failures: list[tuple[str, str]] = []
    written = 0
    for path in progress(files, "frame"):
        try:
            alpha = vm(read_photo(path), str(path))
            write_image(out / f"{path.stem}_mask.png", _finish(alpha, binary), protect=protect)
            written += 1
        except (RelightError, OSError) as exc:  # an unreadable frame: the others still get masks
            failures.append((str(path), str(exc)))
    log.info("%s: %d masks -> %s", folder, written, out)
    return finish_batch(failures, written, many=len(files) > 1)


def _run_video(video: Path, out: Path, vm, binary: bool) -> int:
    """Mask every frame of a video file: frames are read as ``video`` reads them (relight_rt.video.frames: the
    pixel limit checked from the header, a damaged packet or fewer frames than the header announces is an
    error), so the mask video has exactly one frame per frame of the clip, or is not written."""
    from ..video.frames import FrameSink, FrameSource, empty_clip

    as_video = out.suffix.lower() in VIDEO_SUFFIXES
    if out.suffix and not as_video:
        raise RelightError(f"output {out}: expected a video file ({', '.join(VIDEO_SUFFIXES)}) or a folder")
    source = FrameSource(video, matter=vm)  # every frame gets vm's alpha: no mask files, no alpha channel
    sink = FrameSink(video=out if as_video else None, frames_dir=None if as_video else out, fps=source.rate,
                     protect=source.paths)
    count, anyone = 0, False
    with Progress(source.frame_count, "frame") as bar, sink:  # relight_rt.cli.progress
        for frame in source:
            alpha = _finish(frame.mask, binary)
            anyone = anyone or bool((alpha >= 0.5).any())
            sink.write(f"frame_{frame.index:06d}_mask", np.repeat(alpha[..., None], 3, axis=2))
            count += 1
            bar.update()
        empty = empty_clip(video, count, anyone)
        if empty is not None:  # raised inside the sink's block: nothing is kept
            raise empty
    log.info("%s: %d mask frames -> %s", video, count, out)
    return 0
