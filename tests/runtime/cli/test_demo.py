"""relight-rt demo: the bundled example person relit under a preset, photo | relit | light side by side."""

import cv2
import numpy as np
from _graphs import models_dir

from relight_rt import sh
from relight_rt.cli import main
from relight_rt.cli.demo import example_path, side_by_side

__all__ = ["models_dir"]  # fixture


def test_example_is_an_rgba_person():
    img = cv2.imread(str(example_path()), cv2.IMREAD_UNCHANGED)
    assert img.ndim == 3 and img.shape[2] == 4 and img.dtype == np.uint8
    alpha = img[..., 3] > 127
    assert 0.05 < alpha.mean() < 0.9  # a person, not an empty or full mask
    assert img[..., :3][alpha].mean() > 10  # lit, not black


def test_side_by_side_layout():
    photo = np.full((64, 40, 3), 0.5, np.float32)
    relit = np.zeros((64, 40, 3), np.float32)
    out = side_by_side(photo, relit, sh.check_light(np.eye(9, 3)))
    assert out.shape[0] == 64 and out.dtype == np.float32
    assert out.shape[1] > 80 + 20  # two panels, gaps and the sphere
    np.testing.assert_array_equal(out[:, :40], photo)


def test_demo_writes_image(tmp_path, models_dir, monkeypatch, capsys):
    monkeypatch.setenv("RELIGHT_RT_MODELS", str(models_dir))
    out = tmp_path / "demo.png"
    assert main(["demo", "--preset", "golden-hour", "-o", str(out), "--device", "cpu"]) == 0
    img = cv2.imread(str(out))
    example = cv2.imread(str(example_path()), cv2.IMREAD_UNCHANGED)
    assert img.shape[0] == example.shape[0] and img.shape[1] > 2 * example.shape[1]


def test_demo_unknown_preset(tmp_path, models_dir, monkeypatch, capsys):
    monkeypatch.setenv("RELIGHT_RT_MODELS", str(models_dir))
    assert main(["demo", "--preset", "disco", "-o", str(tmp_path / "d.png")]) == 2
    assert "disco" in capsys.readouterr().err
    assert not (tmp_path / "d.png").exists()


def test_demo_takes_every_runtime_option(tmp_path, models_dir, monkeypatch):
    """issue 31: demo accepted --precision/--preprocess/--no-detail and ignored them; they reach the Relighter."""
    from relight_rt import builder

    seen = []
    original = builder.open

    def spy(config, providers=None):
        seen.append(config)
        return original(config, providers=providers)

    monkeypatch.setattr(builder, "open", spy)
    monkeypatch.setenv("RELIGHT_RT_MODELS", str(models_dir))
    monkeypatch.chdir(tmp_path)
    assert main(["demo", "--no-detail", "--preprocess", "reference", "--device", "cpu", "-o", "a.png"]) == 0
    assert len(seen) == 1 and seen[0].detail is False and seen[0].preprocess == "reference"
