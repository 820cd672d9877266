"""The CLI wing (issue 31): every command listed once, one failure printer, and the video job as a library function
(relight_rt.video.job.relight_clip) that the command and each Ray task run. Argument parsing only in cli/, the
library never reaching up into it and no private name across modules: runtime/test_module_imports.py, for the
whole package."""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
from _graphs import models_dir

from relight_rt import cli
from relight_rt.cli.report import finish, finish_batch

__all__ = ["models_dir"]  # fixture

def test_every_command_is_listed_once():
    parser = cli.build_parser()
    commands = next(a for a in parser._actions if a.dest == "command").choices
    assert list(commands) == ["relight", "decompose", "lights", "doctor", "video", "demo", "bench", "composite",
                              "mask", "studio", "import-reference"]  # fmt: skip
    assert len(cli.COMMANDS) == len(commands)


def test_one_failure_printer(capsys):
    assert finish([]) == 0 and capsys.readouterr().err == ""
    assert finish_batch([("a.png", "a.png: broken"), ("b.png", "no person found")], written=3, many=True) == 2
    assert capsys.readouterr().err.splitlines() == [
        "relight-rt: error: a.png: broken", "relight-rt: error: b.png: no person found",
        "relight-rt: 2 failed, 3 written"]  # fmt: skip
    assert finish_batch([("a.png", "bad")], written=0, many=False) == 2
    assert capsys.readouterr().err.splitlines() == ["relight-rt: error: a.png: bad"]


# ------------------------------------------------------------------------------------------- the video job


def _clip(folder: Path, n: int = 3, h: int = 64, w: int = 48) -> Path:
    folder.mkdir(parents=True)
    yy, xx = np.mgrid[0:h, 0:w]
    mask = np.zeros((h, w), np.uint8)
    mask[4:-4, 6:-6] = 255
    for t in range(n):
        grey = (0.5 + 0.3 * np.sin(0.4 * (xx - t)) * np.cos(0.3 * yy)) * 255
        cv2.imwrite(str(folder / f"f_{t:03d}.png"), np.rint(np.dstack([grey] * 3)).astype(np.uint8))
        cv2.imwrite(str(folder / f"f_{t:03d}_mask.png"), mask)
    return folder


def _files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_relight_clip_writes_what_the_video_command_writes(tmp_path, models_dir):
    from relight_rt import LightSpec, RuntimeConfig
    from relight_rt.video.job import ClipLights, relight_clip

    clip = _clip(tmp_path / "clip")
    common = ["--models", str(models_dir), "--device", "cpu", "--batch-size", "2"]
    assert cli.main(["-q", "video", str(clip), "--preset", "studio", "--rotate-per-second", "2", "--frames-out",
                     str(tmp_path / "cmd"), "--lights-out", str(tmp_path / "cmd.npy"), *common]) == 0  # fmt: skip
    lights = ClipLights(spec=LightSpec.preset("studio"), rotate_per_second=2.0)
    report = relight_clip(clip, lights, frames_out=tmp_path / "lib", lights_out=tmp_path / "lib.npy", batch_size=2,
                          config=RuntimeConfig(models=str(models_dir), device="cpu"))  # fmt: skip
    assert report.frames == 3 and report.skipped == () and "turns per second" in report.lights
    assert _files(tmp_path / "lib") == _files(tmp_path / "cmd")
    np.testing.assert_array_equal(np.load(tmp_path / "lib.npy"), np.load(tmp_path / "cmd.npy"))


def test_a_ray_clip_task_runs_the_library_job(tmp_path, models_dir):
    """The Ray task is relight_clip with the clip's settings (no argparse Namespace rebuilt in the worker)."""
    pytest.importorskip("ray")
    from relight_rt import RuntimeConfig
    from relight_rt.apps import ray_jobs as distributed
    from relight_rt.video.job import ClipLights, relight_clip

    clip = _clip(tmp_path / "clip")
    settings = {"src": str(clip), "lights": ClipLights(per_frame=str(tmp_path / "l.npy")), "stabilize": False,
                "frames_out": str(tmp_path / "task"), "config": RuntimeConfig(models=str(models_dir), device="cpu")}
    lights = np.zeros((3, 9, 3), np.float32)
    lights[:, 0] = [[0.4], [0.6], [0.8]]
    np.save(tmp_path / "l.npy", lights)
    row = distributed._video_clip(settings, "job", 1.0)
    assert row["status"] == "ok" and row["output"] == str(tmp_path / "task"), row
    relight_clip(**dict(settings, frames_out=str(tmp_path / "lib")))
    assert _files(tmp_path / "task") == _files(tmp_path / "lib")
    bad = distributed._video_clip(dict(settings, src=str(tmp_path / "missing")), "job", 1.0)
    assert bad["status"] == "failed" and "missing" in bad["error"]


@pytest.mark.parametrize(("kwargs", "match"), [
    ({}, "exactly one"),
    ({"per_frame": "l.npy", "keys": ("studio", "night")}, "exactly one"),
    ({"keys": ("studio",)}, "at least two"),
    ({"per_frame": "l.npy", "rotate_per_second": 1.0}, "turns one light"),
])  # fmt: skip
def test_clip_lights_are_one_kind_of_light(kwargs, match):
    from relight_rt import RelightError
    from relight_rt.video.job import ClipLights

    with pytest.raises(RelightError, match=match):
        ClipLights(**kwargs)


def test_clip_lights_name_the_files_they_read(tmp_path):
    from relight_rt import LightSpec
    from relight_rt.video.job import ClipLights

    assert ClipLights(spec=LightSpec.preset("studio")).paths == ()
    assert ClipLights(per_frame=tmp_path / "l.npy").paths == (str(tmp_path / "l.npy"),)
    keys = ClipLights(keys=("studio", str(tmp_path / "sky.hdr"), LightSpec.file(tmp_path / "k.npy")))
    assert set(keys.paths) == {"studio", str(tmp_path / "sky.hdr"), str(tmp_path / "k.npy")}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ClipLights(spec=LightSpec.envmap(tmp_path / "e.hdr"), rotate_per_second=0.5)
