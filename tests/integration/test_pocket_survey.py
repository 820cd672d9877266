"""benchmarks/pocket_survey.py on a synthetic figure: an arm that closes a pocket of textured backdrop against the body
(held by the matte, which the survey must call a pocket and the dropped candidate rule would open), and the same shape
where the pocket is a fold of the shirt (the person's own colour: the candidate rule must keep it)."""

from __future__ import annotations

import numpy as np
import pytest

H = W = 200
POCKET = (slice(62, 158), slice(66, 80))  # between the arm (x 50-65) and the torso (x 80-140)


def figure(fold: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rgb float32, the mask: the person, the matte: the person and the pocket at alpha 1). The backdrop is two greens
    in 4-px checks with noise; the shirt white; the pocket shows the backdrop, or with ``fold`` a grey fold of the
    shirt (then the mask holds it too)."""
    rng = np.random.default_rng(27)
    yy, xx = np.mgrid[:H, :W]
    checks = ((yy // 4 + xx // 4) % 2).astype(np.float32)[..., None]
    rgb = checks * np.float32([0.15, 0.55, 0.1]) + (1 - checks) * np.float32([0.3, 0.75, 0.2])
    rgb = rgb + rng.normal(0, 0.02, rgb.shape).astype(np.float32)
    person = np.zeros((H, W), bool)
    person[40:62, 50:140] = True  # shoulder
    person[40:H, 80:140] = True  # torso, cut by the bottom border
    person[62:158, 50:66] = True  # arm
    person[158:175, 50:80] = True  # hand against the hip
    rgb[person] = 0.93
    if fold:
        rgb[POCKET] = 0.78
        person[POCKET] = True
    matte = person.copy()
    matte[POCKET] = True
    return np.clip(rgb, 0, 1).astype(np.float32), person, matte.astype(np.float32)


@pytest.fixture(scope="module")
def survey(load_benchmark):
    return load_benchmark("pocket_survey")


def maps(matte: np.ndarray, doubt: float) -> dict[str, np.ndarray]:
    """The matte and the graphs' stand-ins: the coarse matte and every graph hold the pocket at ``doubt``."""
    coarse = matte.copy()
    coarse[POCKET] = doubt
    return {"alpha": matte, "coarse": coarse, "matter": coarse, "selfie": coarse, "pose": coarse}


def test_a_held_gap_the_arm_closes_is_a_pocket_of_backdrop_colour_that_open_pockets_does_not_reach(survey):
    rgb, mask, matte = figure(fold=False)
    rows = survey.regions(rgb, mask, maps(matte, 0.93))
    assert len(rows) == 1
    (row,) = rows
    assert row["kind"] == "pocket" and row["rim_person"] >= 0.8
    assert row["area"] == 96 * 14
    assert row["backdrop"] > 0.9  # the checks' two greens lie near their mean
    assert row["seen"] == 0.0  # held over 0.9 by the coarse matte: open_pockets' search leaves it
    assert row["coarse"] == pytest.approx(0.93)


def test_the_matte_lying_past_the_outline_is_an_outline_region(survey):
    rgb, mask, matte = figure(fold=False)
    matte[POCKET] = 0.0
    matte[60:190, 140:150] = 1.0  # 10 px of backdrop past the torso's right side
    rows = survey.regions(rgb, mask, maps(matte, 1.0))
    assert [r["kind"] for r in rows] == ["outline"]


def test_the_candidate_rule_opens_the_backdrop_pocket_and_keeps_the_shirts_fold(survey):
    rgb, mask, matte = figure(fold=False)
    opened = survey.candidate(rgb, mask, maps(matte, 0.9))
    assert opened["parts"] == 1
    assert opened["background"] > 0.8 * 96 * 14 and opened["person"] == 0.0
    # the graphs sure of it (coarse 1): not a candidate, whatever its colour
    assert survey.candidate(rgb, mask, maps(matte, 1.0))["parts"] == 0
    rgb, mask, matte = figure(fold=True)
    assert survey.candidate(rgb, mask, maps(matte, 0.9))["parts"] == 0


def pose_alone(matte: np.ndarray, selfie: float) -> dict[str, np.ndarray]:
    """The graphs' stand-ins where the pose graph holds the pocket (0.95) and the selfie graph at ``selfie``."""
    m = maps(matte, 0.95)
    m["selfie"] = m["selfie"].copy()
    m["selfie"][POCKET] = selfie
    return m


def test_the_doubted_candidate_opens_backdrop_the_pose_graph_alone_holds_and_keeps_the_shirts_fold(survey):
    rgb, mask, matte = figure(fold=False)
    opened = survey.doubted(rgb, mask, pose_alone(matte, 0.1))
    assert opened["parts"] == 1
    assert opened["background"] > 0.8 * 96 * 14 and opened["person"] == 0.0
    # the selfie graph holding it too: not a candidate, whatever its colour
    assert survey.doubted(rgb, mask, pose_alone(matte, 0.9))["parts"] == 0
    # the shirt's own fold (not the backdrop's colour) stays, pixel by pixel or whole
    rgb, mask, matte = figure(fold=True)
    assert survey.doubted(rgb, mask, pose_alone(matte, 0.1))["parts"] == 0
    assert survey.doubted(rgb, mask, pose_alone(matte, 0.1), share=0.8)["parts"] == 0
