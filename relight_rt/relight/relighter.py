"""The Relighter: decompose a photo of a person, relight it, and put it back at full resolution.

Pipeline (DESIGN.md §1, §4, §5)::

    photo + mask ─► crop/pad/resize (CropGeometry) ─► stage 1 ─► albedo, skin, transport, light
    new light L' ─► diffuse D = clip(albedo ⊙ max(0, T·L'), 0, 1) ─► stage 2 ─► relit (network frame)
    relit ─► back to the input's size and position ─► composited over the background

The Relighter orders the stages and holds the ONNX sessions; the stages live in relight_rt.relight: its graphs
loaded (``graphs``), the Decomposition (``decomposition``), the face pass (``face_pass``), the relighting factor with
full-resolution detail and the exposure (``factor``), the look (``look``), the person over a backdrop (``compose``), a
group person by person (``people``), a light argument resolved (``light_args``) and a Decomposition relit under one
light or K (``lighting``).

Without ``stage2.onnx`` the output is the diffuse image only: ``Relighter.diffuse_only`` is True, a
warning is logged at load, and ``RelightResult.diffuse_only`` says so.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator, Sequence

import numpy as np

from ..engine.config import RuntimeConfig
from ..engine.contract import kind_spec
from ..engine.device_chain import DeviceChain
from ..engine.errors import RelightError
from ..engine.session import Model, find_models, load_model
from ..image.compositing import Background, parse_background
from ..image.crop import CropGeometry
from ..light import exposure as _exposure
from ..person.masks import Matter
from . import compose, light_args
from . import people as per_person
from .compose import Composer, GradeSample, photo_colours
from .decomposition import Decomposition, ImageLike, Memo, RelightResult, diffuse_batch
from .face_pass import FacePass, head_crops
from .factor import Factor
from .graphs import load_stages
from .intake import read_batch
from .kept_rim import KeptRim
from .lighting import Lighting
from .look import prepare_lab
from .network import Network

__all__ = ["Decomposition", "Relighter", "RelightResult", "compose_step", "diffuse_batch"]

log = logging.getLogger(__name__)


class Relighter:
    """Relight photos of people with the relight_rt ONNX models.

    ``Relighter(config)``: decompose a photo once (``decompose``), relight it under as many lights as wanted
    (``relight``, with its layers ``layers``; ``relight_many`` / ``iter_relight`` for K lights in
    stage-2 batches); ``relight_rt.apps.scene.composite(relighter, ...)`` puts it into a scene.

    Args:
        config: a :class:`relight_rt.engine.config.RuntimeConfig`: which models (folder with ``stage1.onnx`` and
            optionally ``stage2.onnx``, without which results are diffuse-only, and ``dvp.onnx``), the device,
            precision ("fp32"; "fp16" graphs ``stage1_fp16.onnx``, ... for CUDA; "int8" for CPU; a graph
            missing in that precision is taken in fp32, logged), preprocessing ("quality" or "reference", the
            reference's resize bit for bit), detail transfer, warm-up and automatic matting. None: the
            defaults (the bundled models, or $RELIGHT_RT_MODELS). Kept once, as ``self.config``.
        matter: the automatic person matte (any relight_rt.person.masks.Matter) for a photo given neither a mask nor an
            alpha channel; one with ``parts`` (``config.matting`` not "off") relights a group person by person.
            None: such a photo is refused. ``relight_rt.open(config)`` hands in the bundled one.
        providers: explicit onnxruntime providers (win over the config's device).

    Raises:
        RelightError: no models found, a model file unreadable or breaking the contract, a bad setting.
    """

    def __init__(self, config: RuntimeConfig | None = None, *, matter: Matter | None = None,
                 providers: list | None = None) -> None:
        if config is None:
            config = RuntimeConfig()
        elif not isinstance(config, RuntimeConfig):
            raise RelightError(f"Relighter: expected a RuntimeConfig (or None), got {type(config).__name__}")
        self.config = config
        self.models_dir = find_models(config.models)
        # a second stage-1 pass on a face seen small (relight_rt.relight.face_pass); photos only, with detail on
        self.face_pass = True
        self.upright = True  # a photo's person lying or tilted: stage 1 sees them upright (relight_rt.relight.upright)
        self._session_args = {"device": config.device, "device_id": config.device_id, "providers": providers}
        self.stage1, self.stage2 = load_stages(self.models_dir, config, self._session_args)
        self._dvp: Model | None = None
        self.matter = matter  # the automatic matte of photos without a mask (None: they need one)
        self._chain = None  # CUDA: stage 1 → shading → stage 2 without host round trips
        if self.stage1.on_cuda and (self.stage2 is None or self.stage2.on_cuda):
            self._chain = DeviceChain(self.stage1, self.stage2, "cuda", config.device_id)
        # what it prepares for a Decomposition (device copies, window), beside the (plain-data) Decomposition, not on it
        self._memo = Memo()
        self._faces = FacePass(self.models_dir)  # face normals (relight_rt.person.face_mesh), loaded on first use
        self._network = Network(self.stage1, self.stage2, self._chain, self._memo, self._faces)
        self._factor = Factor(self._memo, self._faces, config.detail, self._network.own_residual)
        self._composer = Composer(self._memo, self._factor, config.detail)
        self._lighting = Lighting(self._network, self._factor, self._composer, config.detail)
        if config.detail:
            prepare_lab()  # OpenCV's Lab tables, which every relight with detail uses, built beside the first stages
        CropGeometry.from_mask(np.ones((1, 1), np.float32), self.resolution, config.preprocess)  # checks the mode

    # the settings, read from self.config (kept there once)
    @property
    def precision(self) -> str:
        """``self.config.precision``."""
        return self.config.precision

    @property
    def preprocess(self) -> str:
        """``self.config.preprocess``."""
        return self.config.preprocess

    @property
    def detail(self) -> bool:
        """``self.config.detail``."""
        return self.config.detail

    @property
    def resolution(self) -> int:
        """R, stage 1's square input size."""
        return self.stage1.config.resolution

    @property
    def diffuse_only(self) -> bool:
        """True when there is no stage-2 model: results lack the residual (specular, etc.)."""
        return self.stage2 is None

    @property
    def dvp(self) -> Model | None:
        """The deep-video-prior graph (``dvp.onnx`` in the models folder), loaded on first use; None if absent."""
        path = self.models_dir / kind_spec("dvp").filename
        if self._dvp is None and path.is_file():
            self._dvp = load_model(path, "dvp", warmup=False, **self._session_args)
        return self._dvp

    # ------------------------------------------------------------------------------------ stage 1

    def decompose(self, image: ImageLike, mask: ImageLike | None = None) -> Decomposition:
        """Run stage 1 on a photo.

        Args:
            image: a path or an array (H, W, 3) RGB / (H, W, 4) RGBA, uint8 or float in [0, 1].
            mask: a path or an array (H, W), (H, W, 1) or (H, W, 3), binary or soft, same H x W as the
                image; ``"auto"``: the automatic matte; None: the image's alpha channel, else the automatic
                matte (relight_rt.person.masks.resolve_mask).

        Raises:
            RelightError: bad image or mask (see relight_rt.image.io.read_image / read_mask), no mask to be had.
        """
        return self.decompose_batch([image], [mask])[0]

    def decompose_batch(
        self, images: Sequence[ImageLike], masks: Sequence[ImageLike | None] | None = None, *,
        allow_full: bool = False, automatic: Sequence[bool] | None = None,
    ) -> list[Decomposition]:
        """Run stage 1 on several photos in one batch (video frames, folders).

        Args:
            images: photos as for ``decompose`` (any sizes).
            masks: one per image (None entries: alpha, else the automatic matte); None: all None.
            allow_full: accept a mask that covers the whole image (a video frame filled by the person).
            automatic: per image, its mask (an array) is the automatic matte all the same (a video frame's
                ``VideoMatter``: ``Decomposition.automatic``); None: only where intake's matter made it.

        Returns:
            One Decomposition per image, in order.
        """
        if masks is None:
            masks = [None] * len(images)
        if len(masks) != len(images):
            raise RelightError(f"masks: expected one per image ({len(images)}), got {len(masks)}")
        if not images:
            return []
        decs, people, automatic = self._stage1(images, masks, allow_full, faces=self.detail and not allow_full,
                                               automatic=automatic)
        if allow_full:  # video frames skip the work done once per photo (a second pass, the matte's multilevel
            # foreground colours, the light's refit): per frame it would cost more than it shows; the automatic
            # matte's soft edge as the frame shows it (compose FRAME_EDGE) goes with the frame's own colours
            return [self._factor.derive(dec, **photo_colours(dec, True)) if compose.FRAME_EDGE and auto else dec
                    for dec, auto in zip(decs, automatic, strict=True)]
        decs = self._photos(decs)
        for i, crops in enumerate(people):
            if crops is not None:  # a group photo (several people matted): each person decomposed on their own too
                decs[i] = self._group(decs[i], crops)
        # a group relit person by person holds no colours of its own: its people carry theirs (found on first use
        # when it is relit as one); the automatic matte's soft edge as the photo shows it goes with the colours
        return [dec if dec.foreground is not None or dec.people else
                self._factor.derive(dec, **photo_colours(dec, auto)) for dec, auto in zip(decs, automatic, strict=True)]

    def _photos(self, decs: list[Decomposition]) -> list[Decomposition]:
        """With detail: photos' light refit to the transport the relit photo is divided by, faces seen small again."""
        if not self.detail:
            return decs
        decs = [self._factor.refit(dec) for dec in decs]
        if self.face_pass:
            self._look_at_faces(decs)
        return decs

    def _group(self, dec: Decomposition, crops: list) -> Decomposition:
        """A group photo ``dec`` with each of its people (``crops``: their shares of its matte, each in its box,
        relight_rt.relight.people ``PartsMatter``) decomposed on their own, in a window of the photo around them
        with their share as mask (``people.windows``: views); their own colours from the group's matte in their box
        (where two people meet neither is background) and its soft edge as the photo shows it
        (``people.with_shown_edge``)."""
        parts = []
        for image, mask, origin in per_person.windows(dec.image, crops):
            # one person at a time: stage 1 on all of them as one batch grew onnxruntime's arena (which keeps its
            # peak) by the batch's activations, 16 people ~16x one person's
            (part,) = self._photos(self._stage1([image], [mask], False, faces=self.detail)[0])
            parts.append(self._factor.derive(part, origin=origin))
        return per_person.with_shown_edge(self._factor, dec, parts)

    def _look_at_faces(self, decs: list[Decomposition]) -> None:
        """Run stage 1 again on the head of each person whose face it saw small (relight_rt.relight.face_pass), in
        place."""
        todo = head_crops(decs)
        if not todo:
            return
        heads, _, _ = self._stage1([t[3] for t in todo], [t[4] for t in todo], True, faces=True)
        for (i, dec, box, _, _), head in zip(todo, heads, strict=True):
            # the head pass gives the face's transport; the photo's light is the body's estimate (one light for
            # one photo: the change of shading is measured from it in both passes, so the photo's own light
            # gives the photo back everywhere), turned by the face the head pass sees large (``Factor.face_light``)
            dec = self._factor.face_light(dec, head)
            decs[i] = self._factor.derive(dec, head=self._factor.with_light(head, dec.light), head_box=box)
            log.debug("second stage-1 pass on the head at %s", box)

    def _stage1(self, images: Sequence[ImageLike], masks: Sequence, allow_full: bool, faces: bool,
                automatic: Sequence[bool] | None = None) -> tuple[list[Decomposition], list, list]:
        """Stage 1 on a batch: read, resolve masks, crop, run; one Decomposition per image (a photo unless
        ``allow_full``, its face meshes found with ``faces``), per image its people's masks or None, and per image
        whether its mask is the automatic matte (intake's matter made it, or ``automatic`` says so)."""
        matter = self.matter
        group = self.config.matting != "off" and not allow_full  # a group photo: relit person by person
        rgbs, ms, geoms, people, found = read_batch(images, masks, matter, group, allow_full, self.resolution,
                                                    self.preprocess)
        automatic = found if automatic is None else [a or bool(b) for a, b in zip(found, automatic, strict=True)]
        net_imgs = [g.to_network(rgb) for g, rgb in zip(geoms, rgbs, strict=True)]
        net_masks = [g.to_network(m) for g, m in zip(geoms, ms, strict=True)]
        meshes = [self._faces.find(rgb, g.box) if faces else None for g, rgb in zip(geoms, rgbs, strict=True)]
        alone = [self.upright and not allow_full and p is None for p in people]  # may be seen upright (Network)
        outs, on_device = self._network.run_stage1(rgbs, ms, geoms, net_imgs, net_masks, meshes, alone)
        decs = []
        for i, (geom, seen) in enumerate(zip(geoms, outs, strict=True)):
            dec = Decomposition(**seen, network_mask=net_masks[i], network_image=net_imgs[i], mask=ms[i], image=rgbs[i],
                                geometry=geom, photo=not allow_full, face_meshes=meshes[i], automatic=automatic[i])
            if on_device[i] is not None:
                self._memo(dec)["device"] = on_device[i]
            decs.append(dec)
        return decs, people, automatic

    # ------------------------------------------------------------------------------------ lights

    def resolve_light(self, light, dtype=np.float32) -> np.ndarray:
        """Any accepted light argument → (9, 3) RGB SH light: the one place where a light is resolved.

        Accepted: an array (9, 3); a ``Decomposition`` (its estimated light, taken as white as the photo's own
        light is: "light me like that photo"); a :class:`relight_rt.light.spec.LightSpec`; a string or path, read
        by the one rule of relight_rt.light.spec (light file, environment map, photo of a person, or preset name):
        a photo's light is estimated by this Relighter's stage 1, any other needs no model (``LightSpec.resolve``).

        Args:
            light: as above.
            dtype: float32 (default: the dtype the pipeline uses; a light too large for it is refused) or float64
                (a light schedule's keys, turned and interpolated before use).
        """
        return light_args.resolve_light(light, self.decompose, dtype)

    # ------------------------------------------------------------------------------------ relight

    def highlight_inputs(self, dec: Decomposition) -> _exposure.Highlight:
        """What the exposure's highlight guard reads of ``dec`` (relight_rt.relight.exposure_meter
        ``ExposureMeter.highlight_inputs``; the studio's preview samples it)."""
        return self._factor.meter.highlight_inputs(dec)

    def grade_inputs(self, dec: Decomposition) -> GradeSample:
        """What the backdrop's grade reads of ``dec`` whatever the light (compose ``Composer.grade_inputs``)."""
        return self._composer.grade_inputs(dec)

    def kept_rim(self, dec: Decomposition) -> KeptRim | None:
        """The kept background's rim on ``dec``'s outline where ``relight`` over the photo's own background puts it
        (compose ``Composer.shown_rim``: the automatic matte's shown edge of a photo, a video frame's automatic matte
        with ``compose.FRAME_RIM``; None where none is applied: a mask or alpha given, a group relit as one). The
        studio's preview draws it."""
        return self._composer.shown_rim(dec)

    def cast_shadows(self, dec: Decomposition, light) -> tuple[np.ndarray | None, float]:
        """The body pass's cast shadows the final result puts under ``light`` (any light ``resolve_light`` takes) and
        the exposure's lift for them (``Factor.shadow_layer``): (depth (H, W) float32 in [0, 1], input frame, 1 - the
        factor on the shading, or None without one; meter). The studio's preview draws them (relight_rt.apps.studio)."""
        return self._factor.shadow_layer(dec, self.resolve_light(light))

    def head_change(self, dec: Decomposition, light) -> tuple[np.ndarray, np.ndarray] | None:
        """The head pass's change of the relit person's luminance under ``light`` exposed "auto", for the studio's
        preview (compose ``Composer.head_change``; None: no head pass blended)."""
        return self._composer.head_change(dec, self._factor.meter.expose(dec, self.resolve_light(light), "auto"))

    def _prepare(self, image, mask) -> Decomposition:
        if isinstance(image, Decomposition):
            if mask is not None:
                raise RelightError("mask: a Decomposition already has its mask; pass mask only with an image")
            return image
        return self.decompose(image, mask)

    def relight(
        self,
        image: ImageLike | Decomposition,
        light,
        *,
        mask: ImageLike | None = None,
        background: Background | str | os.PathLike | np.ndarray = "original",
        exposure="auto",
    ) -> np.ndarray:
        """Relight a photo (or a Decomposition: decompose once, relight many) under a new light.

        Args:
            image: a photo (see ``decompose``) or a ``Decomposition`` (no stage-1 pass).
            light: see ``resolve_light``: (9, 3) array, LightSpec, light file, HDR map, photo, Decomposition or
                preset.
            mask: the photo's mask (see ``decompose``); not with a Decomposition.
            background: a :class:`relight_rt.image.compositing.Background`, or its shorthand: "original" (the
                photo), "transparent" (RGBA output, alpha = mask), a colour ("black", "#RRGGBB") or an image
                (path or array; fitted to the photo by "cover"). ``Background.original(grade=True)``: the photo's
                background follows the new light by one global grade per channel, the person's change
                (relight_rt.image.compositing); off by default.
            exposure: "auto" (default: the light is scaled so the person keeps its mean luminance, lowered by up
                to a stop where that would put more than 8 % of the person past white), an EV offset from
                auto (+1 twice as bright), or "physical" (the light as given); relight_rt.light.exposure.

        Returns:
            (H, W, 3) float32 RGB in [0, 1] at the input's size ((H, W, 4) RGBA for "transparent"); pixels
            where the mask is 0 are the background's, untouched. ``layers`` gives it with its layers.
        """
        return self._relight(image, light, mask, background, exposure, False)

    def layers(
        self,
        image: ImageLike | Decomposition,
        light,
        *,
        mask: ImageLike | None = None,
        background: Background | str | os.PathLike | np.ndarray = "original",
        exposure="auto",
    ) -> RelightResult:
        """``relight`` with the input-frame layers that made the picture (arguments as for ``relight``).

        Returns:
            A :class:`RelightResult`: ``relight``'s picture as ``.image``, its ``.layers`` ("albedo", "shading",
            "diffuse", "residual", "relit", "mask"; a group's are the group's, decomposed as one) and ``.light``.
        """
        return self._relight(image, light, mask, background, exposure, True)

    def _relight(self, image, light, mask, background, exposure, layers: bool) -> np.ndarray | RelightResult:
        dec = self._prepare(image, mask)
        return self._lighting.one(dec, light, exposure, background, self.resolve_light, layers, keep=image is dec)

    def iter_relight(
        self,
        image: ImageLike | Decomposition,
        lights,
        *,
        mask: ImageLike | None = None,
        background: Background | str | os.PathLike | np.ndarray = "original",
        batch_size: int = 4,
        exposure="auto",
    ) -> Iterator[np.ndarray]:
        """Like ``relight_many`` but yields one (H, W, 3|4) result at a time (for long sweeps and video)."""
        if not isinstance(batch_size, int) or batch_size < 1:
            raise RelightError(f"batch_size: expected a whole number >= 1, got {batch_size!r}")
        dec = self._prepare(image, mask)
        resolved, exposures = light_args.lights_with_exposures(lights, exposure, self.resolve_light)
        yield from self._lighting.each(dec, resolved, exposures, background, batch_size, keep=image is dec)

    def relight_many(
        self,
        image: ImageLike | Decomposition,
        lights,
        *,
        mask: ImageLike | None = None,
        background: Background | str | os.PathLike | np.ndarray = "original",
        batch_size: int = 4,
        exposure="auto",
    ) -> np.ndarray:
        """One stage-1 pass, then K relights through stage 2 in batches of ``batch_size``.

        Args:
            image: a photo or a Decomposition (as for ``relight``).
            lights: (K, 9, 3) array or a list of anything ``resolve_light`` accepts.
            mask, background: as for ``relight``.
            batch_size: lights per stage-2 run.
            exposure: as for ``relight``, for each light on its own.

        Returns:
            (K, H, W, 3) float32 RGB ((K, H, W, 4) for "transparent"); K full-size images are held in memory,
            use ``iter_relight`` for long sweeps.
        """
        dec = self._prepare(image, mask)
        # a list is resolved light by light in iter_relight (a photo's light once); an array is checked here
        count = len(lights) if isinstance(lights, (list, tuple)) else \
            len(light_args.resolve_lights(lights, self.resolve_light))
        bg = parse_background(background)
        out = np.empty((count,) + dec.geometry.frame + (bg.channels,), np.float32)
        results = self.iter_relight(dec, lights, background=bg, batch_size=batch_size, exposure=exposure)
        for i, img in enumerate(results):
            out[i] = img
        return out


def compose_step(relighter: Relighter, dec: Decomposition, light: np.ndarray):
    """A call that runs only the full-resolution half of a relight (the photo times the relighting factor, over
    the photo's own backdrop) for one light, with stage 2's outputs computed once beforehand: what
    ``relight-rt bench --sections compose`` times (relight_rt.cli.bench)."""
    outputs = next(relighter._network.relit(dec, light[None], 1, want_layers=True))
    return lambda: relighter._composer.compose(dec, light, outputs, dec.image)
