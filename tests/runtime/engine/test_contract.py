"""relight_rt.contract: metadata parsing accepts good graphs and names what is wrong with bad ones."""

import pytest

from relight_rt import RelightError
from relight_rt.engine.contract import KINDS, ModelConfig, config_from_metadata


def good(kind="stage1", resolution=256):
    return ModelConfig(kind=kind, resolution=resolution, norm="instance", source="test").metadata()


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_round_trip(kind):
    cfg = config_from_metadata(good(kind, 256), "m.onnx")
    carries_norm = "relight_rt.norm" in KINDS[kind].metadata  # the relighting kinds; not a person matte
    assert cfg.kind == kind and cfg.resolution == 256 and cfg.norm == ("instance" if carries_norm else "")


@pytest.mark.parametrize(
    ("key", "value", "match"),
    [
        ("relight_rt.format", "2", "format"),
        ("relight_rt.kind", "stage3", "kind"),
        ("relight_rt.resolution", "abc", "integer"),
        ("relight_rt.resolution", "100", "multiple of 64"),
        ("relight_rt.color", "BGR", "RGB"),
        ("relight_rt.sh_degree", "3", "sh_degree"),
        ("relight_rt.norm", "layer", "norm"),
    ],
)
def test_bad_values_are_named(key, value, match):
    meta = good()
    meta[key] = value
    with pytest.raises(RelightError, match=match):
        config_from_metadata(meta, "m.onnx")


def test_missing_key():
    meta = good()
    del meta["relight_rt.kind"]
    with pytest.raises(RelightError, match="m.onnx.*relight_rt.kind.*missing"):
        config_from_metadata(meta, "m.onnx")


def test_stage1_needs_fixed_resolution():
    with pytest.raises(RelightError, match="fixed resolution"):
        config_from_metadata(good("stage1", 0))
    assert config_from_metadata(good("stage2", 0)).resolution == 0
