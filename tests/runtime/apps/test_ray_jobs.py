"""relight_rt.apps.ray_jobs on a local Ray (2 CPUs): the same files and failures as the single-process CLI,
a manifest, and a rerun that finishes a killed job without redoing what was done."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from _graphs import OWN_LIGHT, models_dir, person

from relight_rt import RelightError, cli
from relight_rt.apps import ray_jobs as distributed

ray = pytest.importorskip("ray")

__all__ = ["models_dir"]  # fixture

REPO = Path(__file__).resolve().parents[3]
GOOD, BAD = 27, 3


@pytest.fixture(scope="module")
def ray_local():
    """One local Ray for the module (start-up is slow): 2 CPUs, no dashboard, a small object store;
    its workers import this checkout's relight_rt, whichever job (this process or a subprocess) runs."""
    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = distributed.worker_env()["env_vars"]["PYTHONPATH"]
    ray.init(num_cpus=2, include_dashboard=False, object_store_memory=200 * 1024**2, log_to_driver=False,
             runtime_env=distributed.worker_env())  # fmt: skip
    try:
        yield ray.get_runtime_context().gcs_address
    finally:
        ray.shutdown()
        if old is None:
            os.environ.pop("PYTHONPATH", None)
        else:
            os.environ["PYTHONPATH"] = old


def _write(path: Path, rgb: np.ndarray) -> None:
    cv2.imwrite(str(path), cv2.cvtColor((rgb * 255).round().astype(np.uint8), cv2.COLOR_RGB2BGR))


def make_shoot(folder: Path, size=(150, 100)) -> Path:
    """30 photos: 27 good (masks beside them, one RGBA with its alpha, one JPEG) and 3 bad (a truncated
    file, an empty mask, a mask of the wrong size); plus files a folder run must leave alone."""
    folder.mkdir(parents=True)
    h, w = size
    for i in range(30):
        img, mask = person(h, w, seed=i, box=(10 + i % 7, h - 10, 20 + i % 5, w - 20))
        name = folder / f"p{i:02d}.png"
        if i == 3:  # RGBA, the alpha is the mask
            cv2.imwrite(str(name), np.dstack([(img[..., ::-1] * 255).round().astype(np.uint8), mask * 255]))
            continue
        if i == 4:
            name = name.with_suffix(".jpg")
        _write(name, img)
        bad_mask = {11: np.zeros_like(mask), 17: mask[:-7]}.get(i)
        cv2.imwrite(
            str(folder / f"{name.stem}_mask.png"), ((mask if bad_mask is None else bad_mask) * 255).astype(np.uint8)
        )
    data = (folder / "p23.png").read_bytes()
    (folder / "p23.png").write_bytes(data[: len(data) // 2])  # truncated
    _write(folder / "old_relit.png", np.zeros((h, w, 3)))  # an earlier result: not an input
    (folder / ".p05_relit.png.x.tmp.png").write_bytes(b"")  # a killed writer's temporary file
    return folder


@pytest.fixture(scope="module")
def shoot(tmp_path_factory):
    return make_shoot(tmp_path_factory.mktemp("shoot") / "in")


@pytest.fixture(scope="module")
def light_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("light") / "light.npy"
    np.save(path, (OWN_LIGHT * np.array([1.1, 0.9, 0.7])).astype(np.float64))
    return path


def _cli(argv, capsys) -> tuple[int, list[str]]:
    code = cli.main([str(a) for a in argv])
    err = capsys.readouterr().err
    return code, [line for line in err.splitlines() if line.startswith("relight-rt:")]


@pytest.fixture(scope="module")
def single_process(shoot, light_file, models_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("single") / "out"
    code = cli.main(["relight", str(shoot), "--light", str(light_file), "-o", str(out), "--models",
                     str(models_dir), "--device", "cpu"])  # fmt: skip
    assert code == 2
    return out


def _files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.glob("*.png")) if not p.name.startswith(".")}


@pytest.mark.long
def test_same_bytes_and_failures_as_the_single_process_cli(ray_local, shoot, light_file, models_dir,
                                                           single_process, tmp_path, capsys):  # fmt: skip
    argv = ["relight", shoot, "--light", light_file, "--models", models_dir, "--device", "cpu"]
    code1, lines1 = _cli([*argv, "-o", tmp_path / "one"], capsys)
    code2, lines2 = _cli([*argv, "-o", tmp_path / "ray", "--ray", "--ray-batch-size", "4"], capsys)
    assert code1 == code2 == 2
    assert lines1 == lines2 and len(lines1) == BAD + 1, lines2  # three files, then "3 failed, 27 written"
    assert "p11_mask.png" in lines2[0] and "empty" in lines2[0]
    assert "p17_mask.png" in lines2[1] and "143x100" in lines2[1]
    assert "p23.png" in lines2[2] and "cannot decode" in lines2[2]
    one, far = _files(tmp_path / "one"), _files(tmp_path / "ray")
    assert len(far) == GOOD and "old_relit_relit.png" not in far and "p04_relit.png" in far
    assert far == one == _files(single_process)
    rows = distributed.read_manifest(tmp_path / "ray" / distributed.MANIFEST_NAME)
    assert sorted(r["status"] for r in rows) == ["failed"] * BAD + ["ok"] * GOOD
    assert {Path(r["input"]).name for r in rows if r["status"] == "failed"} == {"p11.png", "p17.png", "p23.png"}
    assert all(r["seconds"] > 0 and set(r) >= {"input", "output", "status", "error", "seconds"} for r in rows)


@pytest.mark.long
def test_rerun_after_a_kill_redoes_only_what_is_missing(ray_local, shoot, light_file, models_dir, single_process,
                                                        tmp_path):  # fmt: skip
    out = tmp_path / "out"
    first = distributed.relight_folder(shoot, out, np.load(light_file), models=models_dir, device="cpu",
                                       batch_size=3)  # fmt: skip
    assert first.written == GOOD and first.count("failed") == BAD
    # as a job killed half-way leaves it: the first rows listed, a torn line, some outputs missing,
    # one output written but not yet listed, a temporary file
    manifest = out / distributed.MANIFEST_NAME
    rows = sorted(distributed.read_manifest(manifest), key=lambda r: r["input"])
    kept = [r for r in rows if r["status"] == "ok"][:12]
    unlisted = [r for r in rows if r["status"] == "ok"][12]
    for r in rows:
        if r["status"] == "ok" and r not in kept and r is not unlisted:
            Path(r["output"]).unlink()
    manifest.write_text("".join(json.dumps(r) + "\n" for r in kept) + '{"input": "torn')
    (out / ".p20_relit.png.abc.tmp.png").write_bytes(b"\x89PNG")
    stamps = {r["output"]: os.stat(r["output"]).st_mtime_ns for r in kept}
    time.sleep(0.05)
    again = distributed.relight_folder([str(shoot)], str(out), np.load(light_file), models=models_dir,
                                       device="cpu", batch_size=3)  # fmt: skip
    assert again.skipped == len(kept) and again.written == GOOD - len(kept) and again.count("failed") == BAD
    assert {r["output"] for r in again.rows if r["status"] == "skipped"} == set(stamps)
    assert all(os.stat(p).st_mtime_ns == t for p, t in stamps.items())  # not redone
    assert _files(out) == _files(single_process)
    assert len(distributed.read_manifest(manifest)) == len(kept) + 30  # the torn line is dropped, not fatal
    # a new light is a new job: nothing is skipped
    third = distributed.relight_folder(shoot, out, "studio", models=models_dir, device="cpu", batch_size=8)
    assert third.skipped == 0 and third.written == GOOD


@pytest.mark.long
def test_killed_subprocess_job_then_rerun(ray_local, light_file, models_dir, tmp_path):
    """A real kill: a CLI job on the shared cluster is SIGKILLed once a few outputs exist; the rerun
    leaves every output the manifest lists alone and writes the rest."""
    src = make_shoot(tmp_path / "in", size=(900, 600))  # big enough that 30 photos take seconds
    out = tmp_path / "out"
    argv = [sys.executable, "-m", "relight_rt", "-q", "relight", str(src), "--light", str(light_file), "-o", str(out),
            "--models", str(models_dir), "--device", "cpu", "--ray", ray_local, "--ray-actors", "1",
            "--ray-batch-size", "1"]  # fmt: skip
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen(argv, cwd=REPO, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    manifest = out / distributed.MANIFEST_NAME
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and proc.poll() is None:
        if sum(r["status"] == "ok" for r in distributed.read_manifest(manifest)) >= 4:
            break
        time.sleep(0.02)
    if proc.poll() is not None:
        pytest.fail(f"the job ended before it could be killed: {proc.stderr.read().decode()[-2000:]}")
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    listed = {r["output"] for r in distributed.read_manifest(manifest) if r["status"] == "ok"}
    assert 4 <= len(listed) < GOOD, f"the kill came too late to test a rerun ({len(listed)} done)"
    stamps = {p: os.stat(p).st_mtime_ns for p in listed}
    time.sleep(0.05)
    again = distributed.relight_folder(src, out, np.load(light_file), models=models_dir, device="cpu")
    assert {r["output"] for r in again.rows if r["status"] == "skipped"} == listed
    assert all(os.stat(p).st_mtime_ns == t for p, t in stamps.items())
    assert again.written == GOOD - len(listed) and len(_files(out)) == GOOD


@pytest.mark.long
def test_errors_name_the_problem(ray_local, shoot, light_file, models_dir, tmp_path, capsys):
    code, lines = _cli(["relight", shoot, "--light", light_file, "-o", tmp_path / "o", "--models", models_dir,
                        "--ray", "--ray-batch-size", "0"], capsys)  # fmt: skip
    assert code == 2 and "batch size" in lines[0]
    code, lines = _cli(["relight", shoot, "--light", light_file, "-o", tmp_path / "o", "--models", models_dir,
                        "--ray", "--background", "nope.png"], capsys)  # fmt: skip
    assert code == 2 and "nope.png" in lines[0]


def _clip(folder: Path, n: int, seed: int, mask: bool = True) -> Path:
    folder.mkdir(parents=True)
    for t in range(n):
        img, m = person(64, 48, seed=seed + t, box=(6, 58, 10, 38))
        _write(folder / f"f_{t:03d}.png", img)
        if mask:
            cv2.imwrite(str(folder / f"f_{t:03d}_mask.png"), (m * 255).astype(np.uint8))
    return folder


@pytest.mark.long
def test_video_clips_one_task_each(ray_local, models_dir, tmp_path, capsys):
    clips = [_clip(tmp_path / "a", 4, 0), _clip(tmp_path / "b", 3, 10), _clip(tmp_path / "bad", 2, 20)]
    (clips[2] / "f_001.png").write_bytes(b"\x89PNG\r\n\x1a\n truncated")  # a damaged frame: that clip fails
    common = ["--preset", "studio", "--models", models_dir, "--device", "cpu", "--batch-size", "2"]
    for clip in clips[:2]:
        assert cli.main(["video", str(clip), "--frames-out", str(tmp_path / "single" / clip.name),
                         *map(str, common)]) == 0  # fmt: skip
    code, lines = _cli(["video", *clips, "--frames-out", tmp_path / "far", "--metrics", tmp_path / "m", "--ray",
                        *common], capsys)  # fmt: skip
    assert code == 2 and len(lines) == 2 and "bad" in lines[0], lines
    for clip in clips[:2]:
        assert _files(tmp_path / "far" / clip.name) == _files(tmp_path / "single" / clip.name)
        assert json.loads((tmp_path / "m" / f"{clip.name}_metrics.json").read_text())["frames"] > 1
    manifest = tmp_path / "far" / distributed.MANIFEST_NAME
    assert [r["status"] for r in distributed.read_manifest(manifest)].count("ok") == 2
    code, lines = _cli(["video", *clips[:2], "--frames-out", tmp_path / "far", "--metrics", tmp_path / "m", "--ray",
                        *common], capsys)  # fmt: skip
    assert code == 0
    assert [r["status"] for r in distributed.read_manifest(manifest)][-2:] == ["skipped", "skipped"]


def test_several_clips_need_ray(models_dir, tmp_path, capsys):
    clips = [_clip(tmp_path / "a", 2, 0), _clip(tmp_path / "b", 2, 5)]
    code, lines = _cli(["video", *clips, "--frames-out", tmp_path / "o", "--preset", "studio"], capsys)
    assert code == 2 and "--ray" in lines[0]


def test_manifest_is_checked_against_every_file_read(models_dir, tmp_path, monkeypatch, capsys):
    """issue 35 item 2: ``--manifest`` named a sibling mask, a file of the --mask folder or a model graph, was
    accepted, and a newline was appended to it before Ray started. It is an output like any other: refused,
    before Ray starts, when it is any file the run reads."""

    def no_ray(*args, **kwargs):
        raise AssertionError("Ray started: the manifest should have been refused first")

    monkeypatch.setattr(distributed, "ray_session", no_ray)
    monkeypatch.setenv("RELIGHT_RT_MODELS", str(models_dir))
    monkeypatch.chdir(tmp_path)
    for folder in ("photos", "masks", "clip"):
        (tmp_path / folder).mkdir()
    img, mask = person(150, 100)
    _write(tmp_path / "photos" / "p.png", img)
    cv2.imwrite(str(tmp_path / "photos" / "p_mask.png"), (mask * 255).astype(np.uint8))
    cv2.imwrite(str(tmp_path / "masks" / "q_mask.png"), (mask * 255).astype(np.uint8))
    _write(tmp_path / "clip" / "f_000.png", img)
    cv2.imwrite(str(tmp_path / "clip" / "f_000_mask.png"), (mask * 255).astype(np.uint8))
    graph = sorted(Path(models_dir).glob("*.onnx"))[0]
    runs = [
        (["relight", "photos/p.png", "--preset", "studio", "-o", "out"], "photos/p_mask.png"),
        (["relight", "photos", "--mask", "masks", "--preset", "studio", "-o", "out"], "masks/q_mask.png"),
        (["relight", "photos", "--preset", "studio", "-o", "out"], str(graph)),
        (["video", "clip", "--preset", "studio", "-o", "vout"], "clip/f_000_mask.png"),
        (["video", "clip", "--preset", "studio", "-o", "vout"], str(graph)),
    ]
    for argv, manifest in runs:
        before = Path(manifest).read_bytes()
        code = cli.main([*argv, "--ray", "local", "--manifest", manifest])
        lines = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(lines) == 1 and "refusing to overwrite the input" in lines[0], (argv, lines)
        assert Path(manifest).read_bytes() == before, manifest


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"exposure": "bogus"}, "exposure"),
        ({"exposure": float("nan")}, "exposure"),
        ({"cpus_per_actor": float("nan")}, "CPUs per actor"),
        ({"cpus_per_actor": float("inf")}, "CPUs per actor"),
        ({"cpus_per_actor": "1"}, "CPUs per actor"),
        ({"cpus_per_actor": 0}, "CPUs per actor"),
        ({"cpus_per_actor": 10**400}, "CPUs per actor"),  # np.isfinite's TypeError (fuzz9 review)
        ({"gpus_per_actor": float("nan")}, "GPUs per actor"),
        ({"gpus_per_actor": -1}, "GPUs per actor"),
        ({"mask": "no_such_masks"}, "--mask no_such_masks: not found"),
        ({"config": {"device": "cpu"}}, "config: expected a RuntimeConfig"),
    ],
)
def test_bad_arguments_are_refused_before_ray_starts(tmp_path, monkeypatch, kwargs, match):
    """fuzz9: these reached the Ray session (a cluster started, then every photo failed the same way, or Ray raised
    ValueError / TypeError of its own); now one RelightError before it."""

    def no_ray(*args, **kw):
        raise AssertionError("Ray started: the argument should have been refused first")

    monkeypatch.setattr(distributed, "ray_session", no_ray)
    monkeypatch.chdir(tmp_path)
    img, mask = person(150, 100)
    (tmp_path / "in").mkdir()
    _write(tmp_path / "in" / "p.png", img)
    with pytest.raises(RelightError, match=match):
        distributed.relight_folder("in", "out", np.full((9, 3), 0.3, np.float32), **kwargs)
    with pytest.raises(RelightError, match="inputs: expected"):
        distributed.relight_folder(None, "out", np.full((9, 3), 0.3, np.float32))


def test_a_light_list_holding_true_is_refused_before_ray_starts(monkeypatch):
    """fuzz9 review: np.asarray read [True, 0.5, 0.5] as numbers before sh.check_light saw the list."""

    def no_ray(*args, **kw):
        raise AssertionError("Ray started: the light should have been refused first")

    monkeypatch.setattr(distributed, "ray_session", no_ray)
    with pytest.raises(RelightError, match="true/false"):
        distributed.relight_folder("in", "out", [[True, 0.5, 0.5]] + [[0.0] * 3] * 8)


def test_bad_clips_and_resources_are_refused_before_ray_starts(tmp_path, monkeypatch):
    def no_ray(*args, **kw):
        raise AssertionError("Ray started: the argument should have been refused first")

    monkeypatch.setattr(distributed, "ray_session", no_ray)
    clip = {"src": str(tmp_path / "c.mp4"), "lights": np.full((9, 3), 0.3, np.float32),
            "output": str(tmp_path / "o.mp4")}  # fmt: skip
    manifest = tmp_path / "m.jsonl"
    for clips, kwargs, match in [
        ([clip], {"cpus_per_task": float("nan")}, "CPUs per task"),
        ([clip], {"gpus_per_task": -1}, "GPUs per task"),
        ([{"src": "x"}], {}, "clips: expected relight_clip's settings"),
        (["x.mp4"], {}, "clips: expected relight_clip's settings"),
        (None, {}, "clips: expected a list"),
    ]:
        with pytest.raises(RelightError, match=match):
            distributed.relight_videos(clips, manifest, **kwargs)


def test_manifest_lines_that_do_not_parse_are_left_out(tmp_path):
    """fuzz9: a line of 100000 "[" raised RecursionError and an integer of 5000 digits ValueError (not
    JSONDecodeError) in read_manifest and done_outputs."""
    manifest = tmp_path / "m.jsonl"
    out = tmp_path / "o.png"
    out.write_bytes(b"x")
    good = json.dumps({"output": str(out), "status": "ok", "job": "j"})
    manifest.write_text("[" * 100000 + "\n" + '{"n": ' + "9" * 5000 + "}\n" + good + "\n")
    assert distributed.read_manifest(manifest) == [json.loads(good)]
    assert distributed.done_outputs(manifest, "j") == {str(out.resolve())}
