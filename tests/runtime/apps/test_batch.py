"""relight_rt.apps.batch (the plan and the one-file work shared by the CLI and the Ray actors) and the parts of
relight_rt.apps.ray_jobs that need no Ray: the manifest, and the error when Ray is missing."""

import json
import sys

import cv2
import numpy as np
import pytest
from _graphs import OWN_LIGHT, models_dir, write_person

from relight_rt import RelightError, cli
from relight_rt.apps import batch
from relight_rt.apps import ray_jobs as distributed

__all__ = ["models_dir"]  # fixture


def _photo(folder, name, seed=0):
    return write_person(folder, name, seed, h=60, w=40, box=(5, 55, 10, 30))


def test_plan_leaves_out_the_projects_own_files(tmp_path):
    for name in ("b", "a"):
        _photo(tmp_path, name)
    _photo(tmp_path, "a_relit")  # an earlier result
    (tmp_path / ".a_relit.png.x1.tmp.png").write_bytes(b"")  # a killed writer's temporary file
    plan = batch.plan([str(tmp_path)], tmp_path / "out")
    assert [(s.name, t.name) for s, t in plan.pairs] == [("a.png", "a_relit.png"), ("b.png", "b_relit.png")]
    assert not plan.single and not plan.to_file and plan.failures == []


def test_plan_single_file_missing_input_and_duplicates(tmp_path):
    photo = _photo(tmp_path, "p")
    one = batch.plan([str(photo)], tmp_path / "o.jpg")
    assert one.single and one.to_file and one.pairs == [(photo, tmp_path / "o.jpg")]
    with pytest.raises(RelightError, match="unknown image type"):
        batch.plan([str(photo)], tmp_path / "o.xyz")
    (tmp_path / "x").mkdir()
    (tmp_path / "y").mkdir()
    (tmp_path / "empty").mkdir()
    _photo(tmp_path / "x", "a")
    _photo(tmp_path / "y", "a")
    plan = batch.plan([str(tmp_path / "x"), str(tmp_path / "y"), "nope.png", str(tmp_path / "empty")], tmp_path / "o")
    assert len(plan.pairs) == 1 and len(plan.inputs) == 2
    messages = [m for _, m in plan.failures]
    assert any("not found" in m for m in messages) and any("holds no images" in m for m in messages)
    assert any("would both write" in m for m in messages)


def test_relight_file_writes_atomically_and_refuses_inputs(tmp_path, models_dir):
    from relight_rt.engine.config import RuntimeConfig
    from relight_rt.relight.relighter import Relighter

    photo = _photo(tmp_path, "p")
    r = Relighter(RuntimeConfig(models=models_dir, device="cpu"))
    out = batch.relight_file(r, photo, tmp_path / "p_relit.png", OWN_LIGHT)
    assert cv2.imread(str(out)).shape == (60, 40, 3)
    before = photo.read_bytes()
    with pytest.raises(RelightError, match="refusing to overwrite"):
        batch.relight_file(r, photo, photo, OWN_LIGHT, protect=[photo])
    assert photo.read_bytes() == before
    with pytest.raises(RelightError, match="works with one input"):
        batch.relight_file(r, photo, tmp_path / "q.png", OWN_LIGHT, mask_arg=str(tmp_path / "x"), single=False)
    (tmp_path / "x").mkdir()
    with pytest.raises(RelightError, match="mask folder"):
        batch.relight_file(r, photo, tmp_path / "q.png", OWN_LIGHT, mask_arg=str(tmp_path / "x"), single=False)


def test_manifest_appends_survive_a_torn_line(tmp_path):
    path = tmp_path / "m.jsonl"
    with distributed.ManifestWriter(path) as w:
        w.write([distributed._row("a.png", tmp_path / "a_relit.png", "ok", job="j")])
    with open(path, "a") as f:
        f.write('{"input": "b.png", "outp')  # a job killed mid-line
    (tmp_path / "a_relit.png").write_bytes(b"x")
    with distributed.ManifestWriter(path) as w:
        w.write([distributed._row("c.png", tmp_path / "c_relit.png", "failed", "bad", job="j")])
    rows = distributed.read_manifest(path)
    assert [r["input"] for r in rows] == ["a.png", "c.png"]
    assert json.loads(path.read_text().splitlines()[-1])["status"] == "failed"
    assert distributed.done_outputs(path, "j") == {str((tmp_path / "a_relit.png").resolve())}
    assert distributed.done_outputs(path, "other job") == set()
    with pytest.raises(RelightError, match="refusing to overwrite"):
        distributed.ManifestWriter(tmp_path / "a_relit.png", protect=[tmp_path / "a_relit.png"])


def test_job_key_follows_the_settings():
    light = np.asarray(OWN_LIGHT, np.float32)
    assert distributed.job_key(light=light, mask=None) == distributed.job_key(mask=None, light=light.copy())
    assert distributed.job_key(light=light, mask=None) != distributed.job_key(light=light * 2, mask=None)
    assert distributed.job_key(light=light, mask=None) != distributed.job_key(light=light, mask="m/")


def test_ray_missing_is_one_line_naming_the_extra(tmp_path, models_dir, monkeypatch, capsys):
    _photo(tmp_path, "p")
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray raises ImportError
    code = cli.main(["relight", str(tmp_path), "--preset", "studio", "-o", str(tmp_path / "o"), "--models",
                     str(models_dir), "--ray"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and 'pip install "relight-rt[ray]"' in err
    assert not (tmp_path / "o").exists()  # nothing written before the check
