"""The one place where a Relighter meets the bundled person matte: ``open(config)`` builds the Relighter with the
matter ``config.matting`` asks for (``person_matter``), and ``video_matter`` gives a video job its steady matte.

The relighting core (relight_rt.relight.relighter, relight_rt.relight, relight_rt.video.job) takes its matter handed in
(``Relighter(config, matter=...)``, any relight_rt.person.masks.Matter) and never imports relight_rt.person.matting; the
command line, the demo, batch, Ray and the studio build their Relighter here.
"""

from __future__ import annotations

import importlib.util
import logging
import threading

import numpy as np

from .engine.config import RuntimeConfig
from .engine.errors import RelightError
from .person.masks import Matter
from .relight.relighter import Relighter

log = logging.getLogger(__name__)


def open(config: RuntimeConfig | None = None, *, providers: list | None = None) -> Relighter:  # noqa: A001
    """A Relighter as ``config`` says (default: ``RuntimeConfig()``), with the automatic person matte its
    ``matting`` asks for (``person_matter``); ``providers``: explicit onnxruntime providers.

    Raises:
        RelightError: not a RuntimeConfig; whatever ``Relighter`` raises (no models, a bad model file).
    """
    config = RuntimeConfig() if config is None else config
    if not isinstance(config, RuntimeConfig):
        raise RelightError(f"config: expected a RuntimeConfig, got {type(config).__name__}")
    return Relighter(config, matter=person_matter(config), providers=providers)


def _installed() -> bool:
    """The matting package and its graphs are there."""
    if importlib.util.find_spec(f"{__package__}.person.matting") is None:
        return False
    from .person.matting import find_matting_models

    try:
        find_matting_models()
    except RelightError as exc:  # the graphs are not installed: photos then need a mask or alpha
        log.debug("no automatic matting: %s", exc)
        return False
    return True


class _Lazy:
    """A matter built at its first use (loading the graphs takes ~0.3 s): ``build()`` gives the real one."""

    def __init__(self, build) -> None:
        self._build, self._matter, self._lock = build, None, threading.Lock()

    def _get(self):
        with self._lock:
            if self._matter is None:
                self._matter = self._build()
            return self._matter

    def __call__(self, rgb: np.ndarray, name: str = "image") -> np.ndarray:
        return self._get()(rgb, name=name)


class _LazyPeople(_Lazy):
    """``_Lazy`` for a person matter that keeps each person's share of the matte (``parts``,
    relight_rt.relight.people)."""

    def parts(self, rgb: np.ndarray, name: str = "image"):
        return self._get().parts(rgb, name)

    def part_crops(self, rgb: np.ndarray, name: str = "image"):
        """``parts``, each share held only inside its box (a group photo holds about one photo of shares, not one
        per person: issue 50 bug 1)."""
        return self._get().part_crops(rgb, name)


def person_matter(config: RuntimeConfig) -> Matter | None:
    """The automatic person matte for photos: ``config.matting`` "auto" (the largest person), "all" (everyone,
    each person's share kept) or "off" (None); None as well when the matting graphs are not installed."""
    if config.matting == "off" or not _installed():
        return None
    from .person.matting import shared_matter

    person = "all" if config.matting == "all" else "largest"
    # "largest" keeps the people who stand with that person too (a group posing together): each keeps a share
    return _LazyPeople(lambda: shared_matter(device=config.device, person=person))


def video_matter(config: RuntimeConfig) -> Matter | None:
    """The automatic matte for video frames without a mask (relight_rt.person.matting.VideoMatter: steady over time),
    loaded at its first use (on ``config.device``; ``config.matting`` is about photos); None when the matting
    graphs are not installed."""
    if not _installed():
        return None
    from .person.matting import VideoMatter, shared_matter

    return _Lazy(lambda: VideoMatter(shared_matter(device=config.device)))
