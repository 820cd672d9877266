"""Tests of relight_rt.video.job: sources, masks, light schedules, sinks, streaming memory bound."""

from __future__ import annotations

import gc
import tracemalloc
from pathlib import Path

import cv2
import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.video import metrics
from relight_rt.video.job import (
    DVPModel,
    FrameLayers,
    FrameSink,
    FrameSource,
    LightSchedule,
    batched,
    composite,
    relight_frames,
    relight_video,
)
from relight_rt.video.stabilize import Stabilizer

H, W = 24, 32


class FakeEngine:
    """Stage 1 stand-in in the input frame: albedo = frame + per-frame noise, constant transport;
    render = albedo · shading, composited."""

    def __init__(self, noise: float = 0.0, seed: int = 0):
        self.rng = np.random.default_rng(seed)
        self.noise = noise
        self.batches: list[int] = []

    def decompose(self, images, masks, automatic=None):
        self.batches.append(len(images))
        out = []
        for img, mask in zip(images, masks, strict=True):
            transport = np.zeros((*img.shape[:2], 9), np.float32)
            transport[..., 0] = 3.0
            transport[..., 1] = 1.0
            albedo = np.clip(img + self.rng.normal(0, self.noise, img.shape), 0, 1).astype(np.float32)
            out.append(FrameLayers(img, mask, albedo, transport, None))
        return out

    def render(self, layers, albedo, transport, own_light, light, background):
        relit = np.clip(albedo * np.maximum(transport @ light, 0), 0, 1)
        return composite(relit, layers.image, layers.mask, background)

    def to_input(self, layers, layer):
        return np.array(layer)


def _frame(t: int, h: int = H, w: int = W) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w]
    return (0.5 + 0.3 * np.sin(0.4 * (xx - t)) * np.cos(0.3 * yy))[..., None].repeat(3, 2).astype(np.float32)


def _mask(h: int = H, w: int = W) -> np.ndarray:
    m = np.zeros((h, w), np.uint8)
    m[2:-2, 3:-3] = 255
    return m


def _write_folder(folder: Path, n: int, style: str = "mask_files", h: int = H, w: int = W) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for t in range(n):
        rgb8 = np.rint(_frame(t, h, w) * 255).astype(np.uint8)
        bgr = cv2.cvtColor(rgb8, cv2.COLOR_RGB2BGR)
        if style == "rgba":
            cv2.imwrite(str(folder / f"f_{t:04d}.png"), np.dstack([bgr, _mask(h, w)]))
        else:
            cv2.imwrite(str(folder / f"f_{t:04d}.png"), bgr)
            if style == "mask_files":  # 3-channel 8-bit masks, as the reference's video
                cv2.imwrite(str(folder / f"f_{t:04d}_mask.png"), np.dstack([_mask(h, w)] * 3))
    return folder


def _lights(n: int) -> np.ndarray:
    lights = np.zeros((n, 9, 3), np.float32)
    lights[:, 0] = 0.3
    lights[:, 1] = 0.2 * np.cos(2 * np.pi * np.arange(n) / n)[:, None]
    return lights


@pytest.mark.parametrize("style", ["mask_files", "rgba", "mask_folder"])
def test_folder_source_and_masks(tmp_path, style):
    frames = _write_folder(tmp_path / "in", 3, "none" if style == "mask_folder" else style)
    masks = None
    if style == "mask_folder":
        masks = tmp_path / "masks"
        masks.mkdir()
        for t in range(3):
            cv2.imwrite(str(masks / f"f_{t:04d}.png"), _mask())
    src = FrameSource(frames, masks)
    got = list(src)
    assert len(src) == 3 and len(got) == 3
    assert [f.name for f in got] == ["f_0000", "f_0001", "f_0002"]
    assert got[0].image.shape == (H, W, 3) and got[0].image.dtype == np.float32
    np.testing.assert_allclose(got[1].image, _frame(1), atol=1 / 255)
    np.testing.assert_array_equal(got[0].mask, _mask() / 255.0)


def test_missing_mask_is_an_error(tmp_path):
    frames = _write_folder(tmp_path / "in", 2, "none")
    with pytest.raises(RelightError, match="no mask found"):
        list(FrameSource(frames))


def test_bad_sources(tmp_path):
    with pytest.raises(RelightError, match="does not exist"):
        FrameSource(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(RelightError, match="found none"):
        FrameSource(tmp_path / "empty")
    (tmp_path / "bad.mp4").write_bytes(b"not a video")
    with pytest.raises(RelightError, match="cannot open"):
        FrameSource(tmp_path / "bad.mp4")


def test_video_file_roundtrip_with_mask_folder(tmp_path):
    frames = _write_folder(tmp_path / "in", 5, "none")
    masks = tmp_path / "masks"
    masks.mkdir()
    for t in range(5):
        cv2.imwrite(str(masks / f"m_{t:03d}.png"), _mask())
    video = tmp_path / "in.avi"
    with FrameSink(video=video, fps=10) as sink:
        for f in FrameSource(frames, masks):
            sink.write(f.name, f.image)
    assert video.is_file() and not list(tmp_path.glob(".*tmp*"))
    src = FrameSource(video, masks)
    assert src.fps == pytest.approx(10)
    got = list(src)
    assert len(got) == 5 and got[0].name == "frame_000000"
    assert np.abs(got[2].image - _frame(2)).mean() < 0.05  # MJPG is lossy


def test_batched():
    assert [len(b) for b in batched(iter(range(7)), 3)] == [3, 3, 1]
    with pytest.raises(RelightError, match="batch_size"):
        list(batched(iter(range(3)), 0))


def test_light_schedules():
    lights = _lights(4)
    seq = LightSchedule.sequence(lights)
    np.testing.assert_array_equal(seq(2, 25.0), lights[2])
    with pytest.raises(RelightError, match="covers 4 frames"):
        seq(4, 25.0)
    const = LightSchedule.constant(lights[0])
    np.testing.assert_array_equal(const(100, 25.0), lights[0])
    with pytest.raises(RelightError, match=r"\(N, 9, 3\)"):
        LightSchedule.sequence(np.zeros((4, 9)))
    with pytest.raises(RelightError, match="NaN or Inf"):
        LightSchedule.constant(np.full((9, 3), np.nan))


def test_light_sequence_file(tmp_path):
    np.save(tmp_path / "l.npy", _lights(3))
    assert LightSchedule.from_file(tmp_path / "l.npy").length == 3
    np.save(tmp_path / "bad.npy", np.zeros(3))
    with pytest.raises(RelightError, match="bad.npy"):
        LightSchedule.from_file(tmp_path / "bad.npy")


def test_rotation_schedule_turns_once_per_second():
    sh = pytest.importorskip("relight_rt.light.sh")
    light = np.zeros((9, 3))
    light[0] = 0.5
    light[3] = 0.3  # toward the camera
    rot = LightSchedule.rotating(light, 1.0)
    np.testing.assert_allclose(rot(0, 10.0), light, atol=1e-6)
    np.testing.assert_allclose(rot(10, 10.0), light, atol=1e-5)
    np.testing.assert_allclose(rot(5, 10.0), sh.rotate_z(light, np.pi), atol=1e-5)


def test_pipeline_writes_frames_and_keeps_order(tmp_path):
    frames = _write_folder(tmp_path / "in", 5)
    src = FrameSource(frames)
    engine = FakeEngine()
    out_dir = tmp_path / "out"
    sink = FrameSink(frames_dir=out_dir, video=tmp_path / "o.avi", protect=src.paths)
    report = relight_video(src, LightSchedule.sequence(_lights(5)), sink, engine=engine, stabilizer=Stabilizer(),
                           batch_size=2)
    assert report.frames == 5 and report.seconds_per_frame > 0
    assert engine.batches == [2, 2, 1]
    assert sorted(p.name for p in out_dir.iterdir()) == [f"f_{t:04d}.png" for t in range(5)]
    assert (tmp_path / "o.avi").is_file()


def test_stabiliser_reduces_flicker_in_pipeline(tmp_path):
    frames = _write_folder(tmp_path / "in", 8, h=48, w=64)
    lights = LightSchedule.constant(_lights(1)[0])  # a fixed light: every change is flicker
    scores = {}
    for name, stab in (("raw", None), ("stab", Stabilizer())):
        acc = metrics.TemporalMetrics()
        for f, out, ex in relight_frames(FrameSource(frames), lights, fps=25.0, engine=FakeEngine(noise=0.05),
                                         stabilizer=stab,
                                         with_layers=True):
            acc.update(out, f.mask, f.image, ex["albedo"], ex["transport"], ex["light"])
        scores[name] = acc.result()
    assert scores["stab"].warping_error < 0.7 * scores["raw"].warping_error


def test_sink_refuses_to_overwrite_inputs(tmp_path):
    frames = _write_folder(tmp_path / "in", 2)
    src = FrameSource(frames)
    with pytest.raises(RelightError, match="input folder"):
        FrameSink(frames_dir=frames, protect=src.paths)
    video = tmp_path / "v.avi"
    video.write_bytes(b"x")
    with pytest.raises(RelightError, match="overwrite an input"):
        FrameSink(video=video, protect=[video])
    with pytest.raises(RelightError, match="neither"):
        FrameSink()
    with pytest.raises(RelightError, match="video file name"):
        FrameSink(video=tmp_path / "v.gif")


def test_failure_leaves_no_partial_video(tmp_path):
    frames = _write_folder(tmp_path / "in", 4)
    src = FrameSource(frames)
    with pytest.raises(RelightError, match="covers 2 frames"):
        relight_video(src, LightSchedule.sequence(_lights(2)), FrameSink(video=tmp_path / "o.avi"),
                      engine=FakeEngine(), batch_size=1)
    assert not list(tmp_path.glob("*.avi")) and not list(tmp_path.glob(".*"))


def test_engine_xor_dvp():
    with pytest.raises(RelightError, match="exactly one"):
        list(relight_frames(iter([]), LightSchedule.constant(_lights(1)[0]), fps=25.0))


def test_composite():
    img = np.full((2, 2, 3), 0.5, np.float32)
    relit = np.ones((2, 2, 3), np.float32)
    mask = np.array([[1, 0], [0, 1]], np.float32)
    np.testing.assert_array_equal(composite(relit, img, mask)[0, 1], [0.5, 0.5, 0.5])
    np.testing.assert_array_equal(composite(relit, img, mask, "black")[0, 1], [0, 0, 0])
    soft = np.full((2, 2), 0.5, np.float32)
    np.testing.assert_allclose(composite(relit * 0.5, img, soft, premultiplied=True), composite(relit, img, soft))
    with pytest.raises(RelightError, match="background"):
        composite(relit, img, mask, "no-such-background")


def _peak_bytes(folder: Path) -> int:
    src = FrameSource(folder)
    gc.collect()  # garbage left by earlier tests must not be freed (or grown) inside the measurement
    tracemalloc.start()
    tracemalloc.reset_peak()
    try:
        for _ in relight_frames(src, LightSchedule.constant(_lights(1)[0]), fps=25.0, engine=FakeEngine(),
                                stabilizer=Stabilizer(),
                                batch_size=4):
            pass
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_memory_stays_bounded_on_a_long_clip(tmp_path):
    long_dir = _write_folder(tmp_path / "long", 300)
    short_dir = tmp_path / "short"
    short_dir.mkdir()
    for p in sorted(long_dir.iterdir())[:60]:  # the first 30 frames and their masks
        (short_dir / p.name).write_bytes(p.read_bytes())
    frame_bytes = H * W * 3 * 4
    _peak_bytes(short_dir)  # warm-up: one-time allocations (OpenCV, numpy caches) are not the pipeline's
    short_peak = _peak_bytes(short_dir)
    long_peak = _peak_bytes(long_dir)
    # Holding every frame and its layers would add at least 270 * 4 * frame_bytes (~10 MB); streaming adds
    # only the longer file listing.
    assert long_peak < short_peak + 10 * frame_bytes
    assert long_peak < 120 * frame_bytes


def _identity_dvp(path: Path, kind: str = "dvp") -> Path:
    """A contract-shaped DVP graph that returns the frame times the mask (onnx helper, no torch)."""
    onnx = pytest.importorskip("onnx")
    from onnx import TensorProto, helper

    from relight_rt.engine.contract import ModelConfig

    graph = helper.make_graph(
        [helper.make_node("Mul", ["frame", "mask"], ["relit"])],
        "identity_dvp",
        [helper.make_tensor_value_info("frame", TensorProto.FLOAT, ["N", 3, "H", "W"]),
         helper.make_tensor_value_info("mask", TensorProto.FLOAT, ["N", 1, "H", "W"]),
         helper.make_tensor_value_info("light", TensorProto.FLOAT, ["N", 9, 3])],
        [helper.make_tensor_value_info("relit", TensorProto.FLOAT, ["N", 3, "H", "W"])],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    for k, v in ModelConfig(kind, 0, "instance", "test").metadata().items():
        model.metadata_props.add(key=k, value=v)
    onnx.save(model, str(path))
    return path


def test_dvp_model_applied(tmp_path):
    dvp = DVPModel(_identity_dvp(tmp_path / "dvp.onnx"))
    frames = _write_folder(tmp_path / "in", 3)
    outs = list(relight_frames(FrameSource(frames), LightSchedule.constant(_lights(1)[0]), fps=25.0, dvp=dvp,
                               background="black"))
    f, out, extras = outs[1]
    np.testing.assert_allclose(out, f.image * f.mask[..., None], atol=1e-6)
    assert "albedo" not in extras


def test_dvp_model_checks_kind(tmp_path):
    from _graphs import save, stage2_model

    # a valid graph of another kind: refused by its kind alone (the DVPModel's kind check)
    with pytest.raises(RelightError, match=r"metadata relight_rt\.kind is 'stage2', expected 'dvp' here"):
        DVPModel(save(stage2_model(), tmp_path / "model.onnx"))
    # a DVP-shaped graph labelled stage2: refused as the wrong kind, before its inputs are compared (issue 18)
    with pytest.raises(RelightError, match=r"metadata relight_rt\.kind is 'stage2', expected 'dvp' here"):
        DVPModel(_identity_dvp(tmp_path / "s2.onnx", kind="stage2"))
    with pytest.raises(RelightError, match="does not exist"):
        DVPModel(tmp_path / "none.onnx")
    (tmp_path / "junk.onnx").write_bytes(b"junk")
    with pytest.raises(RelightError, match="not a readable ONNX"):
        DVPModel(tmp_path / "junk.onnx")


def test_empty_mask_frames_pass_through(tmp_path):
    frames = _write_folder(tmp_path / "in", 3)
    cv2.imwrite(str(frames / "f_0001_mask.png"), np.zeros((H, W), np.uint8))
    engine = FakeEngine()
    outs = list(relight_frames(FrameSource(frames), LightSchedule.constant(_lights(1)[0]), fps=25.0, engine=engine,
                               stabilizer=Stabilizer(), with_layers=True))
    np.testing.assert_array_equal(outs[1][1], outs[1][0].image)
    assert engine.batches == [2]
    assert outs[1][2]["transport"].shape == (H, W, 9)


def test_relighter_engine_with_tiny_models(tmp_path, test_data_dir):
    """The runtime's Relighter behind the video pipeline: batched stage 1 equals one-by-one decompose."""
    from relight_rt.engine.config import RuntimeConfig
    from relight_rt.relight.relighter import Relighter
    from relight_rt.video.job import RelighterEngine

    models = tmp_path / "models"
    models.mkdir()
    for kind in ("stage1", "stage2"):
        (models / f"{kind}.onnx").write_bytes((test_data_dir / f"tiny_{kind}.onnx").read_bytes())
    relighter = Relighter(RuntimeConfig(models=models, device="cpu"))
    engine = RelighterEngine(relighter)
    frames = _write_folder(tmp_path / "in", 3, h=96, w=80)
    src = list(FrameSource(frames))
    layers = engine.decompose([f.image for f in src], [f.mask for f in src])
    # one frame through the Relighter (a frame keeps stage 1's light; a photo's decompose refits it)
    (one,) = relighter.decompose_batch([src[1].image], [src[1].mask], allow_full=True)
    np.testing.assert_allclose(layers[1].albedo, one.albedo, atol=1e-5)
    np.testing.assert_allclose(layers[1].transport, one.transport, atol=1e-4)
    assert layers[1].image.shape == (relighter.resolution, relighter.resolution, 3)
    light = _lights(1)[0]
    plain = engine.render(layers[1], layers[1].albedo, layers[1].transport, None, light, "original")
    np.testing.assert_allclose(plain, relighter.relight(one, light), atol=1e-4)
    outs = list(relight_frames(iter(src), LightSchedule.sequence(_lights(3)), fps=25.0, engine=engine,
                               stabilizer=Stabilizer(),
                               batch_size=2, with_layers=True))
    assert [o[1].shape for o in outs] == [(96, 80, 3)] * 3
    assert outs[2][2]["albedo"].shape == (96, 80, 3)


def test_tiny_dvp_graph_runs_on_any_frame_size(test_data_dir):
    dvp = DVPModel(test_data_dir / "tiny_dvp.onnx")
    img = _frame(0, 50, 70)
    mask = _mask(50, 70).astype(np.float32) / 255
    a = dvp([img, img], [mask, mask], _lights(2))
    assert [x.shape for x in a] == [(50, 70, 3)] * 2
    assert np.all(a[0][mask == 0] == 0) and a[0].min() >= 0 and a[0].max() <= 1
    small = DVPModel(test_data_dir / "tiny_dvp.onnx", size=64)([img], [mask], _lights(1))
    assert small[0].shape == (50, 70, 3)


def _run_cli(argv: list[str]) -> int:
    import argparse

    from relight_rt.cli.video import add_parser

    parser = argparse.ArgumentParser(prog="relight-rt")
    add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(argv)
    return args.func(args)


@pytest.fixture()
def tiny_models(tmp_path, test_data_dir) -> Path:
    models = tmp_path / "models"
    models.mkdir()
    for kind in ("stage1", "stage2"):
        (models / f"{kind}.onnx").write_bytes((test_data_dir / f"tiny_{kind}.onnx").read_bytes())
    return models


def test_cli_rotating_light_with_metrics(tmp_path, tiny_models):
    import json

    frames = _write_folder(tmp_path / "in", 4, h=96, w=80)
    out = tmp_path / "out.avi"
    code = _run_cli(["video", str(frames), "-o", str(out), "--frames-out", str(tmp_path / "of"), "--models",
                     str(tiny_models), "--preset", "studio", "--rotate-per-second", "6.25", "--device", "cpu",
                     "--metrics", str(tmp_path / "m.json"), "--batch-size", "3"])
    assert code == 0 and out.is_file() and len(list((tmp_path / "of").iterdir())) == 4
    data = json.loads((tmp_path / "m.json").read_text())
    assert data["frames"] == 4 and data["stabilizer"] is True
    assert np.isfinite([data["temporal_error"], data["warping_error"], data["light_following"]]).all()


def test_cli_sequence_interpolation_and_dvp(tmp_path, tiny_models, test_data_dir):
    frames = _write_folder(tmp_path / "in", 3, h=64, w=64)
    np.save(tmp_path / "l.npy", _lights(3))
    assert _run_cli(["video", str(frames), "--frames-out", str(tmp_path / "a"), "--models", str(tiny_models),
                     "--lights", str(tmp_path / "l.npy"), "--no-stabilize", "--device", "cpu"]) == 0
    assert _run_cli(["video", str(frames), "--frames-out", str(tmp_path / "b"), "--models", str(tiny_models),
                     "--interpolate", "studio", "night", "--device", "cpu"]) == 0
    assert _run_cli(["video", str(frames), "--frames-out", str(tmp_path / "c"), "--dvp",
                     str(test_data_dir / "tiny_dvp.onnx"), "--preset", "studio", "--device", "cpu"]) == 0
    assert len(list((tmp_path / "c").iterdir())) == 3


def test_cli_lights_out_records_the_schedule_for_fit_dvp(tmp_path, tiny_models):
    from relight_rt.video import job as video

    frames = _write_folder(tmp_path / "in", 3, h=64, w=64)
    out = tmp_path / "lights.npy"
    assert _run_cli(["video", str(frames), "--frames-out", str(tmp_path / "relit"), "--models", str(tiny_models),
                     "--preset", "studio", "--rotate-per-second", "2", "--fps", "8", "--no-stabilize",
                     "--lights-out", str(out), "--device", "cpu"]) == 0
    saved = np.load(out, allow_pickle=False)
    schedule = video.LightSchedule.rotating(video.resolve_light("studio"), 2.0)
    assert saved.shape == (3, 9, 3) and saved.dtype == np.float32
    np.testing.assert_allclose(saved, [schedule(i, 8.0) for i in range(3)], atol=1e-6)
    assert not np.allclose(saved[0], saved[1])  # a quarter turn per frame
    # the sequence read back is the one written; it never replaces the input sequence
    with pytest.raises(RelightError, match="input"):
        _run_cli(["video", str(frames), "--frames-out", str(tmp_path / "again"), "--models", str(tiny_models),
                  "--lights", str(out), "--lights-out", str(out), "--device", "cpu"])
    np.testing.assert_array_equal(np.load(out, allow_pickle=False), saved)
    assert not (tmp_path / "again").exists()  # refused before any frame was relit


@pytest.mark.parametrize(
    ("extra", "match"),
    [([], "expected --preset, --light"), (["--interpolate", "studio"], "at least two"),
     (["--lights", "x.npy", "--rotate-per-second", "1"], "not both"),
     (["--preset", "no-such-preset"], "no-such-preset"),
     (["--light", "studio"], "is a preset: use --preset studio")],
)
def test_cli_bad_light_options(tmp_path, tiny_models, extra, match):
    frames = _write_folder(tmp_path / "in", 2)
    with pytest.raises(RelightError, match=match):
        _run_cli(["video", str(frames), "-o", str(tmp_path / "o.avi"), "--models", str(tiny_models), *extra])


def test_cli_needs_an_output(tmp_path):
    frames = _write_folder(tmp_path / "in", 2)
    with pytest.raises(RelightError, match="output"):
        _run_cli(["video", str(frames), "--preset", "studio"])


def test_reference_video_stabiliser_on_real_motion(reference_dir):
    """The reference's walking-person frames (3-channel 8-bit masks): real motion, synthetic layer noise."""
    src = FrameSource(reference_dir / "video")
    assert len(src) == 24

    def small_frames():
        for f in src:
            if f.index >= 8:
                return
            size = (f.image.shape[1] // 4, f.image.shape[0] // 4)
            yield type(f)(f.index, f.name, cv2.resize(f.image, size, interpolation=cv2.INTER_AREA),
                          cv2.resize(f.mask, size, interpolation=cv2.INTER_AREA))

    light = LightSchedule.constant(_lights(1)[0])
    results = {}
    for name, stab in (("raw", None), ("stab", Stabilizer())):
        acc = metrics.TemporalMetrics()
        for f, out, _ in relight_frames(small_frames(), light, fps=25.0, engine=FakeEngine(noise=0.05),
                                        stabilizer=stab):
            acc.update(out, f.mask, f.image)
        results[name] = acc.result()
    assert results["stab"].warping_error < 0.75 * results["raw"].warping_error


def test_resolve_light_file_envmap_and_preset(tmp_path):
    from relight_rt import envmap, lightfile, lights
    from relight_rt.video.job import resolve_light

    np.testing.assert_allclose(resolve_light("studio"), lights.preset("studio"))
    light = lights.preset("rim")
    lightfile.save_light(tmp_path / "l.npy", light)
    np.testing.assert_allclose(resolve_light(tmp_path / "l.npy"), light, atol=1e-6)
    env = envmap.envmap_from_light(light, 32)
    cv2.imwrite(str(tmp_path / "env.hdr"), np.ascontiguousarray(np.maximum(env, 0)[..., ::-1]))
    assert resolve_light(tmp_path / "env.hdr").shape == (9, 3)
    with pytest.raises(RelightError, match="unknown light preset 'no-such-light'"):
        resolve_light("no-such-light")
    with pytest.raises(RelightError, match="not found"):
        resolve_light("no-such-light.npy")


def test_cli_shows_progress_and_one_summary(tmp_path, tiny_models):
    """issue 34: video logged "frame 1 / 24", then nothing until the end, then its summary twice."""
    import os
    import re
    import subprocess
    import sys

    import relight_rt

    frames = _write_folder(tmp_path / "in", 3, h=96, w=80)
    env = {**os.environ, "PYTHONPATH": str(Path(relight_rt.__file__).parents[1])}
    argv = [sys.executable, "-m", "relight_rt", "video", str(frames), "-o", str(tmp_path / "out.avi"), "--models",
            str(tiny_models), "--preset", "studio", "--device", "cpu", "--no-stabilize"]
    proc = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "frame 1 / " not in proc.stderr
    assert len(re.findall(r"s per frame", proc.stderr)) == 1, proc.stderr  # one summary
    # (stderr is a pipe here, so no bar: tests/runtime/cli/test_progress.py checks the bar on a terminal)
    assert "frame/s" not in proc.stderr


def test_a_clip_of_nobody_is_an_error_and_writes_nothing(tmp_path, tiny_models):
    """Issue 50 bug 14: `video` on a clip with nobody in any frame wrote the clip back with exit 0 and not a word."""
    clip = tmp_path / "grey.avi"
    writer = cv2.VideoWriter(str(clip), cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 96))
    for _ in range(3):
        writer.write(np.full((96, 64, 3), 128, np.uint8))
    writer.release()
    out, frames = tmp_path / "out.avi", tmp_path / "of"
    with pytest.raises(RelightError, match="no person found in any of the 3 frames"):
        _run_cli(["video", str(clip), "-o", str(out), "--frames-out", str(frames), "--models", str(tiny_models),
                  "--preset", "studio", "--device", "cpu"])  # fmt: skip
    assert not out.exists() and not frames.exists() and not list(tmp_path.glob(".*"))  # no folder left either
