"""Video frames in and out for relight_rt.video: sources (video file or frame folder, with masks) and sinks.

- :class:`FrameSource` reads a video file (``cv2.VideoCapture``) or a folder of frames, one frame at a
  time, with its mask: a mask folder (``STEM.*`` / ``STEM_mask.*``, else sorted order), per-frame
  ``STEM_mask.*`` files beside the frames (the reference layout), the alpha channel of RGBA frames,
  or a mask video; every mask is read by the photos' rule (relight_rt._io.read_mask: grey, colour
  through Rec. 601 grey). An empty mask is allowed (nobody in that frame).
- :class:`FrameSink` writes a video file (``cv2.VideoWriter`` into a temporary file, renamed when
  complete, deleted on failure) and/or PNG frames (each atomic, relight_rt._io.write_image), and
  refuses to overwrite an input.

Frames are RGB float32 (H, W, 3) in [0, 1]; masks float32 (H, W) in [0, 1].
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ._errors import RelightError
from ._io import IMAGE_SUFFIXES, read_image, read_mask, write_image

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v")
_FOURCC = {".mp4": "mp4v", ".m4v": "mp4v", ".mov": "mp4v", ".avi": "MJPG", ".mkv": "MJPG"}


# ---------------------------------------------------------------------------------------------
# images


def read_frame(path: str | os.PathLike) -> np.ndarray:
    """Read an image file as RGB(A) float32 (H, W, 3|4) in [0, 1] (relight_rt._io.read_image)."""
    return read_image(path, "frame")


def read_mask_file(path: str | os.PathLike, shape: tuple[int, int]) -> np.ndarray:
    """Read a frame's mask file as float32 (H, W) in [0, 1], by the photos' rule (relight_rt._io.read_mask).

    A frame may have nobody in it: an empty (or full) mask is accepted.
    """
    return read_mask(path, shape, "mask", allow_empty=True)


# ---------------------------------------------------------------------------------------------
# sources


@dataclass(frozen=True)
class Frame:
    """One input frame: ``index`` from 0, ``name`` (file stem or frame_NNNNNN), RGB, mask."""

    index: int
    name: str
    image: np.ndarray  # (H, W, 3) float32 RGB [0, 1]
    mask: np.ndarray  # (H, W) float32 [0, 1]


class FrameSource:
    """Frames of a video file or a folder of images, with their masks, read one at a time.

    Args:
        path: a video file or a folder of frames (sorted by file name; ``*_mask.*`` files excluded).
        masks: None (per-frame ``STEM_mask.*`` beside the frames, else the alpha channel of RGBA
            frames), a folder (``STEM.*`` or ``STEM_mask.*``; for a video, or frames without a
            match, the folder's images in sorted order), or a mask video file.

    Attributes:
        fps: frames per second (from the video; 25 for a folder unless given).
        frame_count: number of frames (a video container's count may be approximate).
        paths: the input files (never to be overwritten).
    """

    def __init__(self, path: str | os.PathLike, masks: str | os.PathLike | None = None, fps: float | None = None):
        self.path = Path(path)
        self.masks = None if masks is None else Path(masks)
        if not self.path.exists():
            raise RelightError(f"{self.path}: input video or folder does not exist")
        self._files: list[Path] | None = None
        if self.path.is_dir():
            self._files = sorted(p for p in self.path.iterdir()
                                 if p.suffix.lower() in IMAGE_SUFFIXES and not p.stem.endswith("_mask"))
            if not self._files:
                raise RelightError(f"{self.path}: expected image frames ({', '.join(IMAGE_SUFFIXES)}), found none")
            self.frame_count = len(self._files)
            self.fps = float(fps or 25.0)
        else:
            cap = cv2.VideoCapture(str(self.path))
            if not cap.isOpened():
                raise RelightError(f"{self.path}: OpenCV cannot open this video")
            self.frame_count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
            self.fps = float(fps or cap.get(cv2.CAP_PROP_FPS) or 25.0)
            cap.release()
        self._mask_files: list[Path] | None = None
        if self.masks is not None:
            if not self.masks.exists():
                raise RelightError(f"{self.masks}: mask folder or video does not exist")
            if self.masks.is_dir():
                self._mask_files = sorted(p for p in self.masks.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        self.paths = tuple(self._files or (self.path,))

    def __len__(self) -> int:
        return self.frame_count

    def _mask_path(self, index: int, frame_path: Path | None) -> Path | None:
        if frame_path is not None:
            folder = self.masks if self._mask_files is not None else frame_path.parent
            for stem in ((f"{frame_path.stem}_mask",) if self._mask_files is None
                         else (frame_path.stem, f"{frame_path.stem}_mask")):
                for suffix in (".png", frame_path.suffix, *IMAGE_SUFFIXES):
                    candidate = folder / f"{stem}{suffix}"
                    if candidate.is_file() and candidate != frame_path:
                        return candidate
        if self._mask_files is not None:
            if index >= len(self._mask_files):
                raise RelightError(f"{self.masks}: expected a mask for frame {index}, the folder has "
                                   f"{len(self._mask_files)} masks")
            return self._mask_files[index]
        return None

    def __iter__(self) -> Iterator[Frame]:
        where_of = lambda frame_path, index: frame_path or f"{self.path} frame {index}"  # noqa: E731
        mask_cap = None
        if self.masks is not None and self._mask_files is None:
            mask_cap = cv2.VideoCapture(str(self.masks))
            if not mask_cap.isOpened():
                raise RelightError(f"{self.masks}: OpenCV cannot open this mask video")
        cap = None if self._files is not None else cv2.VideoCapture(str(self.path))
        try:
            index = 0
            while True:
                if cap is None:
                    if index >= len(self._files):
                        return
                    frame_path = self._files[index]
                    rgba = read_frame(frame_path)
                    name = frame_path.stem
                else:
                    ok, bgr = cap.read()
                    if not ok:
                        return
                    frame_path = None
                    rgba = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
                    name = f"frame_{index:06d}"
                shape = rgba.shape[:2]
                if mask_cap is not None:
                    ok, mbgr = mask_cap.read()
                    if not ok:
                        raise RelightError(f"{self.masks}: mask video ended before frame {index}")
                    mask = read_mask(cv2.cvtColor(mbgr, cv2.COLOR_BGR2RGB), shape, f"{self.masks} frame {index}",
                                     allow_empty=True)
                else:
                    mask_path = self._mask_path(index, frame_path)
                    if mask_path is not None:
                        mask = read_mask_file(mask_path, shape)
                    elif rgba.shape[2] == 4:
                        mask = read_mask(rgba[..., 3], shape, f"{where_of(frame_path, index)} alpha", allow_empty=True)
                    else:
                        where = where_of(frame_path, index)
                        raise RelightError(f"{where}: no mask found (expected a STEM_mask file, a --masks folder "
                                           f"or an RGBA frame)")
                yield Frame(index, name, np.ascontiguousarray(rgba[..., :3]), mask)
                index += 1
        finally:
            if cap is not None:
                cap.release()
            if mask_cap is not None:
                mask_cap.release()


def batched(frames: Iterator[Frame] | FrameSource, batch_size: int) -> Iterator[list[Frame]]:
    """Group a stream of frames into lists of at most ``batch_size`` (never reads ahead further)."""
    if batch_size < 1:
        raise RelightError(f"batch_size: expected a positive integer, got {batch_size}")
    batch: list[Frame] = []
    for frame in frames:
        batch.append(frame)
        if len(batch) == batch_size:
            yield batch
            batch = []
    if batch:
        yield batch


# ---------------------------------------------------------------------------------------------
# sinks


class FrameSink:
    """Writes relit frames to a video file and/or a folder of PNGs; nothing half-written is left.

    Args:
        video: output video path (.mp4 → mp4v, .avi/.mkv → MJPG) or None.
        frames_dir: output folder for NAME.png frames or None.
        fps: frame rate of the video.
        protect: input paths that must never be overwritten.
    """

    def __init__(self, video: str | os.PathLike | None = None, frames_dir: str | os.PathLike | None = None,
                 fps: float = 25.0, protect: Sequence[os.PathLike | str] = ()):
        if video is None and frames_dir is None:
            raise RelightError("output: expected a video file and/or a frames folder, got neither")
        protected = {Path(p).resolve() for p in protect}
        self._protect = tuple(protected)
        self.video = None if video is None else Path(video)
        self.frames_dir = None if frames_dir is None else Path(frames_dir)
        if self.video is not None:
            if self.video.suffix.lower() not in _FOURCC:
                raise RelightError(f"{self.video}: expected a video file name ending in {sorted(_FOURCC)}")
            if self.video.resolve() in protected:
                raise RelightError(f"{self.video}: refusing to overwrite an input")
        if self.frames_dir is not None:
            self.frames_dir.mkdir(parents=True, exist_ok=True)
            if self.frames_dir.resolve() in {p.parent for p in protected}:
                raise RelightError(f"{self.frames_dir}: refusing to write frames into the input folder")
        self.fps = float(fps)
        self._writer: cv2.VideoWriter | None = None
        self._tmp: Path | None = None
        self.count = 0

    def write(self, name: str, rgb: np.ndarray) -> None:
        """Add one frame (H, W, 3) RGB float [0, 1]."""
        if self.frames_dir is not None:
            write_image(self.frames_dir / f"{name}.png", rgb, self._protect)
        if self.video is not None:
            if self._writer is None:
                self.video.parent.mkdir(parents=True, exist_ok=True)
                self._tmp = self.video.with_name(f".{self.video.stem}.tmp{os.getpid()}{self.video.suffix}")
                fourcc = cv2.VideoWriter_fourcc(*_FOURCC[self.video.suffix.lower()])
                self._writer = cv2.VideoWriter(str(self._tmp), fourcc, self.fps, (rgb.shape[1], rgb.shape[0]))
                if not self._writer.isOpened():
                    raise RelightError(f"{self.video}: OpenCV cannot write this video format")
            bgr = cv2.cvtColor(np.clip(np.rint(rgb * 255.0), 0, 255).astype(np.uint8), cv2.COLOR_RGB2BGR)
            self._writer.write(bgr)
        self.count += 1

    def close(self, ok: bool = True) -> None:
        """Finish the video (rename into place when ``ok``; delete the partial file otherwise)."""
        if self._writer is not None:
            self._writer.release()
            self._writer = None
            if ok:
                os.replace(self._tmp, self.video)
            elif self._tmp.exists():
                self._tmp.unlink()

    def __enter__(self) -> FrameSink:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(ok=exc_type is None)
