"""Video frames in and out for relight_rt.video.job: sources (video file or frame folder, with masks) and sinks.

Two backends for video files: PyAV (the optional ``video`` extra, ``pip install "relight-rt[video]"``; its
wheels carry FFmpeg with libx264) and OpenCV (``cv2.VideoCapture`` / ``cv2.VideoWriter``), used when PyAV is
not installed (a note is logged once).

- :class:`FrameSource` reads a video file or a folder of frames, one frame at a time, with its mask: a mask
  folder (``STEM.*`` / ``STEM_mask.*``, else sorted order), per-frame ``STEM_mask.*`` files beside the frames
  (the reference layout), the alpha channel of RGBA frames, or a mask video; every mask is read by the
  photos' rule (relight_rt.image.io.read_mask: grey, colour through Rec. 601 grey). An empty mask is allowed
  (nobody in that frame). Every frame must decode and have the first frame's size, and a video must give
  as many frames as its header announces; otherwise the source raises RelightError, or, with
  ``skip_bad=True``, leaves the frame out and records it in ``skipped``.
- :class:`FrameSink` writes a video file and/or PNG frames (each atomic, relight_rt.image.io.write_image) and
  refuses to overwrite an input. The video goes into a temporary file created exclusively, with an
  unpredictable name, in the target folder (``tempfile.mkstemp``), renamed into place when complete and
  deleted on failure. With PyAV: H.264 (yuv420p, even width and height: an odd last row or column is
  repeated), the frame rate as an exact fraction, and the audio of ``audio_from`` copied packet by packet
  (no re-encoding; an audio codec the output container cannot hold is left out with a warning). With
  OpenCV: MPEG-4 part 2 (.mp4) or MJPEG (.avi/.mkv), no audio.

Frames keep their place in the video when others are left out (``Frame.index``, from the timestamps with
PyAV), so the light schedule and the masks (a mask video's frame at the same place, a mask folder's in
sorted order) stay aligned after a damaged stretch.

Frames are RGB float32 (H, W, 3) in [0, 1]; masks float32 (H, W) in [0, 1].
"""

from __future__ import annotations

import fractions
import logging
import os
import tempfile
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..engine.errors import RelightError
from ..engine.files import ProtectedPaths, current_umask, same_file
from ..engine.limits import check_pixels, require_file_or_folder
from ..image.io import IMAGE_SUFFIXES, read_image, read_mask, write_image

log = logging.getLogger(__name__)

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v")
_FOURCC = {".mp4": "mp4v", ".m4v": "mp4v", ".mov": "mp4v", ".avi": "MJPG", ".mkv": "MJPG"}
_EXACT_COUNT = (".mp4", ".m4v", ".mov", ".avi")  # containers whose header holds the frame count (OpenCV path)
_noted: set[str] = set()
MAX_FPS = 1000  # frames per second: high-speed cameras reach it; container time bases overflow far above it


def check_fps(fps) -> None:
    """Raise RelightError unless ``fps`` is None or a frame rate in (0, MAX_FPS]."""
    if fps is None:
        return
    try:
        value = float(fps)
    except (TypeError, ValueError, OverflowError):
        raise RelightError(f"fps: expected a number, got {fps!r}") from None
    if not (np.isfinite(value) and 0 < value <= MAX_FPS):
        raise RelightError(f"fps: must be > 0 and at most {MAX_FPS}, got {value:g}")


def _av():
    """The PyAV module, or None when the ``video`` extra is not installed (noted once in the log)."""
    try:
        import av
    except ImportError:
        if "av" not in _noted:
            _noted.add("av")
            log.info('PyAV is not installed: video through OpenCV (MPEG-4 part 2, no audio); for H.264 with the '
                     'audio kept: pip install "relight-rt[video]"')
        return None
    return av


def has_pyav() -> bool:
    """True when PyAV (the ``video`` extra) is installed and used for video files."""
    return _av() is not None


# ---------------------------------------------------------------------------------------------
# images


def read_frame(path: str | os.PathLike) -> np.ndarray:
    """Read an image file as RGB(A) float32 (H, W, 3|4) in [0, 1] (relight_rt.image.io.read_image)."""
    return read_image(path, "frame")


def read_mask_file(path: str | os.PathLike, shape: tuple[int, int]) -> np.ndarray:
    """Read a frame's mask file as float32 (H, W) in [0, 1], by the photos' rule (relight_rt.image.io.read_mask).

    A frame may have nobody in it: an empty (or full) mask is accepted.
    """
    return read_mask(path, shape, "mask", allow_empty=True)


# ---------------------------------------------------------------------------------------------
# video files


@dataclass(frozen=True)
class VideoInfo:
    """What a video file's header says: frames (0 = unknown), frame rate, size, audio."""

    frames: int
    rate: fractions.Fraction
    width: int
    height: int
    has_audio: bool
    exact_count: bool


def _still_image(path: Path) -> RelightError:
    return RelightError(f"{path}: is a still image; `video` takes a video file or a folder of frames "
                        f"(for one photo use `relight`)")


def probe(path: str | os.PathLike, name: str = "video") -> VideoInfo:
    """Read a video file's header (PyAV, else OpenCV); the size is checked against the pixel limit.

    Raises:
        RelightError: not a video (unreadable, a still image, no video stream), frames too large.
    """
    path = Path(path)
    if path.suffix.lower() in IMAGE_SUFFIXES:
        raise _still_image(path)
    av = _av()
    if av is not None:
        try:
            with av.open(str(path)) as container:
                if container.format.name == "image2" or container.format.name.endswith("_pipe"):
                    raise _still_image(path)
                if not container.streams.video:
                    raise RelightError(f"{path}: holds no video stream")
                stream = container.streams.video[0]
                rate = stream.average_rate or stream.guessed_rate or fractions.Fraction(25)
                info = VideoInfo(int(stream.frames or 0), fractions.Fraction(rate), stream.codec_context.width,
                                 stream.codec_context.height, bool(container.streams.audio), stream.frames > 0)
        except av.error.FFmpegError as exc:
            raise RelightError(f"{path}: cannot open this {name} ({exc.strerror or exc})") from None
    else:
        cap = cv2.VideoCapture(str(path))
        try:
            if not cap.isOpened():
                raise RelightError(f"{path}: OpenCV cannot open this {name}")
            fps = cap.get(cv2.CAP_PROP_FPS)
            rate = fractions.Fraction(fps).limit_denominator(1001000) if fps and np.isfinite(fps) and fps > 0 else 25
            info = VideoInfo(max(0, int(cap.get(cv2.CAP_PROP_FRAME_COUNT))), fractions.Fraction(rate),
                             int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)), False,
                             path.suffix.lower() in _EXACT_COUNT)
        finally:
            cap.release()
    check_pixels(info.width, info.height, f"{name} {path}")
    return info


def _decoded_frames(path: Path, name: str, on_bad: Callable[[str, int], None] | None = None
                    ) -> Iterator[tuple[int, np.ndarray]]:
    """(position, RGB uint8 (H, W, 3)) for each frame of a video file, one at a time.

    The position is the frame's place in the video (from its timestamp with PyAV, so frames after a
    skipped packet keep theirs; the running count with OpenCV). A packet that cannot be decoded raises
    RelightError, or, with ``on_bad``, is skipped after ``on_bad(message, position)``.
    """
    av = _av()
    if av is None:
        cap = cv2.VideoCapture(str(path))
        if not cap.isOpened():
            raise RelightError(f"{path}: OpenCV cannot open this {name}")
        try:
            position = 0
            while True:
                ok, bgr = cap.read()
                if not ok:
                    return
                yield position, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
                position += 1
        finally:
            cap.release()
    try:
        container = av.open(str(path))
    except av.error.FFmpegError as exc:
        raise RelightError(f"{path}: cannot open this {name} ({exc.strerror or exc})") from None
    with container:
        stream = container.streams.video[0]
        # no frame threading: a decoding error then belongs to the packet just sent (so a skipped frame's place
        # is known), and decoding costs little beside relighting
        rate = stream.average_rate or stream.guessed_rate
        start = stream.start_time or 0
        last = -1

        def place(pts) -> int:  # the frame's position from its timestamp, never going back
            if pts is None or not rate or not stream.time_base:
                return last + 1
            return max(last + 1, round(float((pts - start) * stream.time_base * rate)))

        for packet in container.demux(stream):
            try:
                frames = packet.decode()
            except av.error.FFmpegError as exc:
                where = f"{path}: {name} packet at {float(packet.pts * packet.time_base):.3f} s" \
                    if packet.pts is not None and packet.time_base else f"{path}: a {name} packet"
                if on_bad is None:
                    raise RelightError(f"{where} cannot be decoded ({exc.strerror or exc}); the file is damaged "
                                       "(--skip-bad-frames leaves such frames out and reports them)") from None
                on_bad(f"{where} cannot be decoded", place(packet.pts))
                continue
            for frame in frames:
                last = place(frame.pts)
                rgb = frame.to_ndarray(format="rgb24")
                turns = round(frame.rotation / 90) % 4  # display matrix (phone videos), as OpenCV applies it
                yield last, np.ascontiguousarray(np.rot90(rgb, turns)) if turns else rgb


# ---------------------------------------------------------------------------------------------
# sources


@dataclass(frozen=True)
class Frame:
    """One input frame: ``index`` from 0, ``name`` (file stem or frame_NNNNNN), RGB, mask, and whether the mask is
    the automatic matte (``FrameSource``'s matter; False: a mask or alpha channel given, the user's word)."""

    index: int
    name: str
    image: np.ndarray  # (H, W, 3) float32 RGB [0, 1]
    mask: np.ndarray  # (H, W) float32 [0, 1]
    automatic: bool = False


def _image_files(folder: Path) -> list[Path]:
    """Image files of a folder, sorted, without hidden files (an interrupted writer's temporary files)."""
    return sorted(p for p in folder.iterdir()
                  if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith("."))


class FrameSource:
    """Frames of a video file or a folder of images, with their masks, read one at a time.

    Args:
        path: a video file or a folder of frames (sorted by file name; ``*_mask.*`` files and hidden files
            excluded).
        masks: None (per-frame ``STEM_mask.*`` beside the frames, else the alpha channel of RGBA
            frames), a folder (``STEM.*`` or ``STEM_mask.*``; for a video, or frames without a
            match, the folder's images in sorted order), or a mask video file.
        fps: frames per second (None: the video's; 25 for a folder).
        skip_bad: leave out frames that cannot be decoded or differ in size from the first, recording each
            in ``skipped`` (the caller reports them and fails), instead of raising RelightError.

    Attributes:
        fps: frames per second (float); rate: the same as an exact fraction (for the writer).
        frame_count: number of frames (from the header for a video; 0 when it does not say).
        paths: every input file (frames, masks, mask video): never to be overwritten.
        skipped: descriptions of the frames left out (``skip_bad``).
        has_audio: the video file has an audio stream (kept by a PyAV FrameSink given ``audio_from``).
    """

    def __init__(self, path: str | os.PathLike, masks: str | os.PathLike | None = None, fps: float | None = None,
                 skip_bad: bool = False, matter=None):
        self.path = Path(path)
        self.auto_masks = isinstance(masks, str) and masks == "auto"
        self.masks = None if masks is None or self.auto_masks else Path(masks)
        self.matter = matter  # frames without a mask: alpha = matter(rgb, name); "auto" masks: every frame
        if self.auto_masks and matter is None:
            raise RelightError("masks 'auto': no automatic matting model is available")
        self.skip_bad = bool(skip_bad)
        self.skipped: list[str] = []
        self.lost = 0  # frames left out (a damaged stretch of a video may lose many in one message)
        check_fps(fps)
        if not self.path.exists():
            raise RelightError(f"{self.path}: input video or folder does not exist")
        require_file_or_folder(self.path, "input video")  # a FIFO would block for ever
        self._files: list[Path] | None = None
        self._info: VideoInfo | None = None
        self.has_audio = False
        if self.path.is_dir():
            self._files = [p for p in _image_files(self.path) if not p.stem.endswith("_mask")]
            if not self._files:
                raise RelightError(f"{self.path}: expected image frames ({', '.join(IMAGE_SUFFIXES)}), found none")
            self.frame_count = len(self._files)
            self.rate = fractions.Fraction(fps or 25).limit_denominator(1001000)
        else:
            self._info = probe(self.path)
            self.frame_count = self._info.frames
            self.has_audio = self._info.has_audio
            self.rate = fractions.Fraction(fps).limit_denominator(1001000) if fps else self._info.rate
        self.fps = float(self.rate)
        self._mask_files: list[Path] | None = None
        inputs = list(self._files or (self.path,))
        if self._files is not None:  # STEM_mask files beside the frames
            inputs += [p for p in _image_files(self.path) if p.stem.endswith("_mask")]
        if self.masks is not None:
            if not self.masks.exists():
                raise RelightError(f"{self.masks}: mask folder or video does not exist")
            require_file_or_folder(self.masks, "mask video")
            if self.masks.is_dir():
                self._mask_files = _image_files(self.masks)
                inputs += self._mask_files
            else:
                probe(self.masks, "mask video")
                inputs.append(self.masks)
        self.paths = tuple(inputs)

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

    def _bad(self, message: str, frames: int = 1) -> None:
        """``frames`` frames that cannot be used: raise, or record them when skipping bad frames."""
        if not self.skip_bad:
            raise RelightError(f"{message} (--skip-bad-frames leaves such frames out and reports them)")
        self.skipped.append(f"{message}, skipped")
        self.lost += frames

    def _images(self) -> Iterator[tuple[int, str, Path | None, np.ndarray | None]]:
        """(index, name, file or None, RGB(A) float32 image) per frame; the image is None for a bad frame."""
        if self._files is not None:
            for index, frame_path in enumerate(self._files):
                try:
                    image = read_frame(frame_path)
                except RelightError as exc:
                    self._bad(str(exc))
                    image = None
                yield index, frame_path.stem, frame_path, image
            return
        lost_before = self.lost
        decoded, index = 0, 0  # index: the next frame's position in the video

        def on_bad(message: str, position: int) -> None:  # one packet: one frame
            self._bad(f"{message} (frame {position})")

        for index, rgb in _decoded_frames(self.path, "video", on_bad if self.skip_bad else None):
            yield index, f"frame_{index:06d}", None, rgb.astype(np.float32) / 255.0
            decoded += 1
        info = self._info
        missing = info.frames - decoded - (self.lost - lost_before) if info is not None and info.exact_count else 0
        if missing > 0:
            self._bad(f"{self.path}: the video's header announces {info.frames} frames, {missing} of them could "
                      f"not be read (a damaged file)", missing)

    def _matte(self, rgba: np.ndarray, where, shape: tuple[int, int]) -> np.ndarray:
        alpha = self.matter(np.ascontiguousarray(rgba[..., :3]), name=str(where))
        return read_mask(np.asarray(alpha, np.float32), shape, f"{where} automatic matte", allow_empty=True)

    def __iter__(self) -> Iterator[Frame]:
        mask_frames = None
        if self.masks is not None and self._mask_files is None:
            mask_frames = _decoded_frames(self.masks, "mask video")
        shape = None
        try:
            for index, name, frame_path, rgba in self._images():
                if rgba is None:
                    continue
                if shape is None:
                    shape = rgba.shape[:2]
                elif rgba.shape[:2] != shape:
                    where = frame_path or f"{self.path} frame {index}"
                    self._bad(f"{where}: frame is {rgba.shape[1]}x{rgba.shape[0]}, the first frame is "
                              f"{shape[1]}x{shape[0]} (W x H)")
                    continue
                automatic = False
                if self.auto_masks:
                    mask = self._matte(rgba, frame_path or f"{self.path} frame {index}", shape)
                    automatic = True
                elif mask_frames is not None:
                    mpos, mrgb = next(mask_frames, (None, None))
                    while mrgb is not None and mpos < index:  # the masks of frames left out
                        mpos, mrgb = next(mask_frames, (None, None))
                    if mrgb is None:
                        raise RelightError(f"{self.masks}: mask video ended before frame {index}")
                    mask = read_mask(mrgb, shape, f"{self.masks} frame {index}", allow_empty=True)
                else:
                    mask_path = self._mask_path(index, frame_path)
                    if mask_path is not None:
                        mask = read_mask_file(mask_path, shape)
                    elif rgba.shape[2] == 4:
                        where = frame_path or f"{self.path} frame {index}"
                        mask = read_mask(rgba[..., 3], shape, f"{where} alpha", allow_empty=True)
                    elif self.matter is not None:
                        mask = self._matte(rgba, frame_path or f"{self.path} frame {index}", shape)
                        automatic = True
                    else:
                        where = frame_path or f"{self.path} frame {index}"
                        raise RelightError(f"{where}: no mask found (expected a STEM_mask file, a --masks folder "
                                           f"or an RGBA frame)")
                yield Frame(index, name, np.ascontiguousarray(rgba[..., :3]), mask, automatic)
        finally:
            if mask_frames is not None:
                mask_frames.close()


def empty_clip(name, frames: int, anyone: bool, hint: str = "") -> RelightError | None:
    """The one error of a clip read to its end with no frame, or with nobody in any frame (as a photo of nobody is
    an error, so is a clip of nobody: issue 50 bug 14); None for a clip with a person. ``hint``: what the caller
    adds after the message ("; give masks ...")."""
    if frames == 0:
        return RelightError(f"{name}: no frames could be read")
    if not anyone:
        return RelightError(f"{name}: no person found in any of the {frames} frames{hint}")
    return None


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


class _AVWriter:
    """H.264 (yuv420p) through PyAV into an open file, with the audio of ``audio_from`` copied."""

    def __init__(self, av, file, suffix: str, rate: fractions.Fraction, width: int, height: int,
                 audio_from: Path | None):
        self.av = av
        self.file = file
        self.audio_from = audio_from
        self.index = 0
        try:
            self._start(suffix, rate, width, height, audio_from)
        except av.error.FFmpegError as exc:
            if not self.audio:
                raise
            # the container refuses the input's audio codec (e.g. Vorbis in .mp4): start again without it
            log.warning("%s: its audio (%s) cannot go into a %s file, left out: %s", audio_from,
                        ", ".join(s.codec_context.name for _, s in self.audio), suffix, exc.strerror or exc)
            self.abort()
            file.seek(0)
            file.truncate()
            self._start(suffix, rate, width, height, None)

    def _start(self, suffix: str, rate: fractions.Fraction, width: int, height: int, audio_from: Path | None):
        """Open the container and its streams and write the header (where an unsupported codec shows)."""
        av = self.av
        fmt = {".mkv": "matroska", ".avi": "avi", ".mov": "mov"}.get(suffix, "mp4")
        self.container = av.open(self.file, mode="w", format=fmt)
        codec = "mjpeg" if suffix == ".avi" else "libx264"
        self.stream = self.container.add_stream(codec, rate=rate)
        self.stream.width, self.stream.height = width + width % 2, height + height % 2
        self.stream.pix_fmt = "yuvj420p" if codec == "mjpeg" else "yuv420p"
        if codec == "libx264":
            self.stream.options = {"crf": "18", "preset": "fast"}
        self.audio = []
        if audio_from is not None:
            with av.open(str(audio_from)) as src:
                for a in src.streams.audio:
                    try:
                        self.audio.append((a.index, self.container.add_stream_from_template(a)))
                    except (ValueError, av.error.FFmpegError) as exc:
                        log.warning("%s: audio stream %d (%s) cannot go into %s, left out: %s", audio_from, a.index,
                                    a.codec_context.name, suffix, exc)
        self.container.start_encoding()

    def write(self, rgb8: np.ndarray) -> None:
        h, w = rgb8.shape[:2]
        if (h % 2, w % 2) != (0, 0):  # 4:2:0 needs even sizes: repeat the last row / column
            rgb8 = cv2.copyMakeBorder(rgb8, 0, h % 2, 0, w % 2, cv2.BORDER_REPLICATE)
        frame = self.av.VideoFrame.from_ndarray(rgb8, format="rgb24")
        frame.pts = self.index
        self.index += 1
        self.container.mux(self.stream.encode(frame))

    def finish(self) -> None:
        self.container.mux(self.stream.encode(None))
        if self.audio:
            streams = dict(self.audio)
            with self.av.open(str(self.audio_from)) as src:
                wanted = [s for s in src.streams.audio if s.index in streams]
                for packet in src.demux(wanted):
                    if packet.dts is None:  # the demuxer's flush packet
                        continue
                    packet.stream = streams[packet.stream.index]
                    self.container.mux(packet)
        self.container.close()

    def abort(self) -> None:
        try:
            self.container.close()
        except Exception:  # noqa: BLE001  (closing a half-written container after another error)
            pass


def _make_folder(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; returns the ones created, deepest first."""
    missing = []
    p = folder
    while not p.exists() and p.parent != p:
        missing.append(p)
        p = p.parent
    folder.mkdir(parents=True, exist_ok=True)
    return missing


class FrameSink:
    """Writes relit frames to a video file and/or a folder of PNGs; nothing half-written is left.

    Args:
        video: output video path (.mp4/.m4v/.mov/.mkv: H.264 with PyAV, MPEG-4 part 2 or MJPEG with OpenCV;
            .avi: MJPEG) or None.
        frames_dir: output folder for NAME.png frames or None.
        fps: frame rate of the video (a float or a fractions.Fraction, e.g. FrameSource.rate).
        protect: input paths that must never be overwritten (nor the folders holding them written into).
        audio_from: a video file whose audio streams are copied into the output (PyAV only).

    Raises:
        RelightError: no output, an unknown video type, fps not > 0, an output that is an input; ``write``:
            a frame of another size than the first.
    """

    def __init__(self, video: str | os.PathLike | None = None, frames_dir: str | os.PathLike | None = None,
                 fps: float = 25.0, protect: Sequence[os.PathLike | str] = (),
                 audio_from: str | os.PathLike | None = None):
        if video is None and frames_dir is None:
            raise RelightError("output: expected a video file and/or a frames folder, got neither")
        check_fps(fps)
        self._made: list[Path] = []  # folders this sink created: removed again on a failure
        self._protect = ProtectedPaths(protect)  # checked for every frame written: resolved once
        self.video = None if video is None else Path(video)
        self.frames_dir = None if frames_dir is None else Path(frames_dir)
        if self.video is not None:
            if self.video.suffix.lower() not in _FOURCC:
                raise RelightError(f"{self.video}: expected a video file name ending in {sorted(_FOURCC)}")
            if self._protect.find(self.video) is not None:
                raise RelightError(f"{self.video}: refusing to overwrite an input")
        if self.frames_dir is not None:
            if any(same_file(self.frames_dir, folder) for folder in {p.parent for p in self._protect}):
                raise RelightError(f"{self.frames_dir}: refusing to write frames into the input folder")
            self._made += _make_folder(self.frames_dir)
        self.rate = fps if isinstance(fps, fractions.Fraction) else fractions.Fraction(float(fps)).limit_denominator(
            1001000)
        self.fps = float(self.rate)
        self.audio_from = None if audio_from is None else Path(audio_from)
        self._writer = None
        self._file = None
        self._tmp: Path | None = None
        self._size: tuple[int, int] | None = None
        self._frames: list[Path] = []  # PNG frames written so far: removed when the sink closes on a failure
        self.count = 0

    def _open(self, width: int, height: int) -> None:
        folder = self.video.parent
        self._made += _make_folder(folder)
        suffix = self.video.suffix.lower()
        fd, tmp = tempfile.mkstemp(prefix=f".{self.video.name}.", suffix=f".tmp{suffix}", dir=folder)
        self._tmp = Path(tmp)
        self._fd_closed = False
        try:
            self._start(fd, width, height, suffix)
        except BaseException:  # no writer yet, so close() would not see the file: remove it here
            if self._file is not None:
                self._file.close()
            elif not self._fd_closed:
                os.close(fd)
            if self._writer is not None and not isinstance(self._writer, _AVWriter):
                self._writer.release()
            self._file, self._writer = None, None
            self._tmp.unlink(missing_ok=True)
            raise

    def _start(self, fd: int, width: int, height: int, suffix: str) -> None:
        av = _av()
        if av is not None:
            self._file = os.fdopen(fd, "wb")  # PyAV writes through the descriptor mkstemp opened
            try:
                self._writer = _AVWriter(av, self._file, suffix, self.rate, width, height, self.audio_from)
            except av.error.FFmpegError as exc:
                raise RelightError(f"{self.video}: cannot write this video ({exc.strerror or exc})") from None
            if (width % 2, height % 2) != (0, 0):
                log.info("%s: %dx%d is odd; H.264 4:2:0 needs even sizes, the last row/column is repeated",
                         self.video, width, height)
            return
        os.close(fd)  # cv2.VideoWriter opens by name: the file mkstemp made exclusively, unguessable name
        self._fd_closed = True
        if self.audio_from is not None and "audio" not in _noted:
            _noted.add("audio")
            log.warning('%s: the audio is not kept without PyAV (pip install "relight-rt[video]")', self.video)
        fourcc = cv2.VideoWriter_fourcc(*_FOURCC[suffix])
        self._writer = cv2.VideoWriter(str(self._tmp), fourcc, self.fps, (width, height))
        if not self._writer.isOpened():
            raise RelightError(f"{self.video}: OpenCV cannot write this video format")

    def write(self, name: str, rgb: np.ndarray) -> None:
        """Add one frame (H, W, 3) RGB float [0, 1]; every frame must have the first frame's size."""
        h, w = rgb.shape[:2]
        if self._size is None:
            self._size = (w, h)
        elif self._size != (w, h):
            raise RelightError(f"frame {name} is {w}x{h}, the video's frames are {self._size[0]}x{self._size[1]} "
                               "(W x H)")
        if self.frames_dir is not None:
            self._frames.append(write_image(self.frames_dir / f"{name}.png", rgb, self._protect))
        if self.video is not None:
            if self._writer is None:
                self._open(w, h)
            rgb8 = np.clip(np.rint(rgb * 255.0), 0, 255).astype(np.uint8)
            if isinstance(self._writer, _AVWriter):
                try:
                    self._writer.write(rgb8)
                except self._writer.av.error.FFmpegError as exc:
                    raise RelightError(f"{self.video}: cannot encode frame {name} ({exc.strerror or exc})") from None
            else:
                self._writer.write(cv2.cvtColor(rgb8, cv2.COLOR_RGB2BGR))
        self.count += 1

    def close(self, ok: bool = True) -> None:
        """Finish the video (rename into place when ``ok``; delete the partial file and the PNG frames this sink
        wrote otherwise: a failed run leaves no partial output)."""
        frames, self._frames = self._frames, []
        if not ok:
            for path in frames:
                path.unlink(missing_ok=True)
        try:
            self._close_writer(ok)
        finally:
            if not ok:
                self._remove_made()

    def _remove_made(self) -> None:
        """The folders this sink created, where a failure left them empty (a failed run leaves no new folder)."""
        made, self._made = self._made, []
        for folder in sorted(made, key=lambda p: len(p.parts), reverse=True):  # the deepest first
            try:
                folder.rmdir()
            except OSError:  # not empty (another output, a frame someone else put there) or gone: leave it
                pass

    def _close_writer(self, ok: bool) -> None:
        writer, self._writer = self._writer, None
        if writer is None:
            return
        try:
            if isinstance(writer, _AVWriter):
                if ok:
                    try:
                        writer.finish()
                    except writer.av.error.FFmpegError as exc:
                        raise RelightError(f"{self.video}: cannot finish the video ({exc.strerror or exc})") from None
                else:
                    writer.abort()
                self._file.close()
            else:
                writer.release()
            if ok:
                os.chmod(self._tmp, 0o666 & ~current_umask())  # mkstemp makes 0600; give the file the usual permissions
                os.replace(self._tmp, self.video)
        finally:
            if self._file is not None and not self._file.closed:
                self._file.close()
            if self._tmp is not None:
                self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> FrameSink:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(ok=exc_type is None)
