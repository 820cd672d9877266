"""``relight-rt decompose --format exr|png16``: compositor passes from the command line
(relight_rt.apps.render_passes)."""

import json

import numpy as np
import pytest
from _cli import in_folder, run
from _graphs import OWN_LIGHT, models_dir, write_person

__all__ = ["models_dir"]  # fixture


@pytest.fixture
def work(tmp_path, models_dir, monkeypatch):
    in_folder(tmp_path, models_dir, monkeypatch)
    np.save(tmp_path / "light.npy", OWN_LIGHT.astype(np.float64))
    write_person(tmp_path)
    return tmp_path


@pytest.mark.parametrize(("fmt", "suffix"), [("exr", ".exr"), ("png16", ".png")])
def test_decompose_writes_the_passes(work, capsys, fmt, suffix):
    code, _, err = run(["decompose", "p.png", "--format", fmt, "--light", "light.npy", "--exposure", "physical",
                        "-o", "passes", "--device", "cpu"], capsys)
    assert code == 0, err
    names = {p.name for p in (work / "passes").iterdir()}
    assert {"albedo" + suffix, "normal" + suffix, "residual" + suffix, "passes.json", "light.json"} <= names
    doc = json.loads((work / "passes" / "passes.json").read_text())
    assert doc["format"] == fmt
    light = json.loads((work / "passes" / "light.json").read_text())
    np.testing.assert_allclose(light["sh"], OWN_LIGHT, rtol=1e-5)  # physical: the light as given


def test_decompose_without_a_light_uses_the_photos_own(work, capsys):
    code, _, err = run(["decompose", "p.png", "--format", "exr", "-o", "passes", "--device", "cpu"], capsys)
    assert code == 0, err
    own = json.loads((work / "passes" / "light_photo.json").read_text())["sh"]
    new = json.loads((work / "passes" / "light.json").read_text())["sh"]
    np.testing.assert_allclose(new, own, rtol=1e-4, atol=1e-6)  # auto exposure keeps the photo's own light


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["--preset", "night"], "add --format exr"),  # a light without passes
        (["--format", "tiff"], "invalid choice"),
        (["--format", "exr", "--preset", "nope"], "unknown light preset"),
    ],
)
def test_decompose_passes_refuses(work, capsys, argv, match):
    code, _, err = run(["decompose", "p.png", *argv, "-o", "passes", "--device", "cpu"], capsys)
    assert code == 2 and match in err
    assert "Traceback" not in err and not (work / "passes").exists()


def test_decompose_passes_never_write_over_the_photo(work, capsys):
    (work / "out").mkdir()
    (work / "out" / "alpha.exr").symlink_to(work / "p.png")
    code, _, err = run(["decompose", "p.png", "--format", "exr", "-o", "out", "--device", "cpu"], capsys)
    assert code == 2 and "refusing to overwrite" in err
    assert [p.name for p in (work / "out").iterdir()] == ["alpha.exr"]  # none of the passes
