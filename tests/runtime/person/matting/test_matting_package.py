"""relight_rt.person.matting is a package split along its concepts; the names users, docs and benchmarks import from
``relight_rt.person.matting`` keep working (the module was one 917-line file until issue 31)."""

import pytest

from relight_rt.person import matting

# named in README, docs/, models/README.md, benchmarks/ and the CLI
USED = ["PersonMatter", "VideoMatter", "outline_flicker", "shared_matter", "find_matting_models", "as_rgb",
        "estimate_foreground", "refine_edges", "bundled_models_dir", "Region", "crop_region", "person_box",
        "POSE_FILE", "ROI_FILE", "FACE_FILE", "MIN_PERSON_FRACTION"]


@pytest.mark.parametrize("name", sorted(set(matting.__all__) | set(USED)))
def test_public_name_is_there(name):
    assert getattr(matting, name) is not None

