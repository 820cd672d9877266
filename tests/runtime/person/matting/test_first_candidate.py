"""The largest person does not hang on where the pose graph's re-centring wandered (matte39): a person reached from
a region where the pose graph saw nobody is tried after the other candidates, and the portrait check looks at the
region first given too. Synthetic stand-ins for the graphs: the cases where the first candidate is wrong."""

from __future__ import annotations

import numpy as np
import pytest

from relight_rt.person import matting as M
from relight_rt.person.matting import _candidate, _largest
from relight_rt.person.matting._segmentation import Person


class _BrightPose:
    """A stand-in for the pose graph: on the first region it is shown, unsure (0.4) and seeing the whole lit body
    (canvas above ``first_bar``); after, sure (1.0) and seeing only the brightest part (above 0.8): as on the mirrored
    p193, 0.494 on the whole, then sure on the child in front."""

    def __init__(self, first_bar: float):
        self.runs = 0
        self.first_bar = first_bar

    def run(self, feeds):
        canvas = feeds["image"][0].transpose(1, 2, 0)
        bar = self.first_bar if self.runs == 0 else 0.8
        seg = np.where(canvas.mean(2) > bar, 5.0, -5.0).astype(np.float32)
        presence = 0.4 if self.runs == 0 else 1.0
        self.runs += 1
        return {"segmentation": seg[None, None], "presence": np.array([[presence]], np.float32)}


def _square(region: M.Region, box: tuple[int, int, int, int], presence: float, start: float | None = None) -> Person:
    """A person whose segmentation is ``box`` (x0, y0, x1, y1, image pixels) on ``region``'s canvas."""
    x0, y0, _, _ = region.box()
    k = 256 / region.side
    logits = np.full((256, 256), -5.0, np.float32)
    bx0, by0, bx1, by1 = box
    logits[int((by0 - y0) * k) : int((by1 - y0) * k), int((bx0 - x0) * k) : int((bx1 - x0) * k)] = 5.0
    return Person(region, logits, presence, start=start)


@pytest.mark.parametrize(("rule", "first_bar", "checked_first"), [
    (True, 0.4, True),  # re-centred onto a part of what the first region showed: that region is checked too
    (False, 0.4, False),  # without the rule only the settled person is looked at
    (True, 0.8, False),  # the first region showed the same square: nothing walked off, no check
])  # fmt: skip
def test_portrait_check_looks_at_the_region_first_given(monkeypatch, rule, first_bar, checked_first):
    rgb = np.full((400, 400, 3), 0.2, np.float32)
    rgb[40:, 120:280] = 0.5  # a body going on past the bottom ...
    rgb[40:120, 160:240] = 1.0  # ... and a bright part high up, which the re-centring settles on
    matter = M.PersonMatter()
    matter.pose = _BrightPose(first_bar)
    checked = []

    def selfie(roi, rgb_, region, presence):  # the selfie graph's answer on the region checked: a portrait
        checked.append(region)
        return Person(region, np.full((256, 256), 5.0, np.float32), presence, "roi")

    monkeypatch.setattr(_candidate, "roi_person", selfie)
    monkeypatch.setattr(_candidate, "is_portrait", lambda roi, shape: True)
    monkeypatch.setattr(_candidate, "reframed", lambda roi, rgb_, p: p)
    monkeypatch.setattr(_candidate, "confirmed", lambda roi, rgb_, p, find: p)
    monkeypatch.setattr(_candidate, "START_PORTRAIT", rule)
    monkeypatch.setattr(matter, "find_faces", lambda rgb_, every=False: [])
    first = M.Region(120.0, 250.0, 500.0)  # off the body's middle, past the bottom (y 0-500 on a 400-px photo)
    found = matter.segment(rgb, first)
    assert matter.pose.runs >= 2  # re-centred from the first region
    if checked_first:  # the settled person ends far above the bottom; the first region is checked and is a portrait
        assert found.source == "roi" and len(checked) == 1 and checked[0].box()[3] >= 400  # (within the photo)
    else:  # no check: the bright square alone
        assert found.source == "pose" and not checked and found.region.box()[3] < 400
        assert found.start == pytest.approx(0.4)  # the first region's presence, kept


@pytest.mark.parametrize(("start", "other", "expected"), [
    (0.005, (100, 60, 300, 380), "other"),  # reached from nobody: the larger person the others find is taken
    (0.6, (100, 60, 300, 380), "walked"),  # the pose graph saw someone from the start: kept, as before
    (0.005, (200, 200, 230, 240), "walked"),  # the others find no one larger: kept
])  # fmt: skip
def test_person_reached_from_nobody_gives_way_to_a_larger_one(monkeypatch, start, other, expected):
    rgb = np.full((400, 400, 3), 0.2, np.float32)
    matter = M.PersonMatter()
    region = M.Region(200.0, 200.0, 400.0)
    walked = _square(region, (300, 120, 360, 180), 0.907, start)  # a sign beside her (p170 mirrored)
    larger = _square(region, other, 0.998)
    monkeypatch.setattr(matter, "find_people", lambda rgb_, **k: [(60000.0, (40.0, 20.0, 380.0, 390.0))])
    monkeypatch.setattr(_largest, "person_at", lambda m, rgb_, box, face, *a, **k: walked if face is None else None)
    monkeypatch.setattr(matter, "find_faces", lambda rgb_, every=False: [])
    monkeypatch.setattr(_largest, "everyone", lambda m, rgb_, tall=0.0: [larger])
    matter.face = None  # no close faces either
    found, blobs = _largest.largest(matter, rgb)
    assert len(found) == 1 and len(blobs) == 1
    assert found[0] is (larger if expected == "other" else walked)
    monkeypatch.setattr(_largest, "WALKED_LAST", False)
    assert _largest.largest(matter, rgb)[0][0] is walked  # without the rule the first candidate is taken


@pytest.mark.parametrize(("other", "expected"), [
    ((200, 200, 230, 240), "walked"),  # a small passer-by in another blob: the set-aside person (a back view) kept
    ((100, 60, 300, 380), "other"),  # a larger person in another blob: taken
])  # fmt: skip
def test_a_later_blob_displaces_a_person_reached_from_nobody_only_when_larger(monkeypatch, other, expected):
    rgb = np.full((400, 400, 3), 0.2, np.float32)
    matter = M.PersonMatter()
    region = M.Region(200.0, 200.0, 400.0)
    walked = _square(region, (150, 100, 260, 330), 0.9, 0.005)  # someone seen from behind: no face, low first presence
    later = _square(region, other, 0.998)
    blobs = [(60000.0, (100.0, 80.0, 300.0, 340.0)), (2000.0, (190.0, 190.0, 240.0, 250.0))]
    monkeypatch.setattr(matter, "find_people", lambda rgb_, **k: blobs)
    monkeypatch.setattr(_largest, "person_at", lambda m, rgb_, box, *a, **k: walked if box == blobs[0][1] else later)
    monkeypatch.setattr(matter, "find_faces", lambda rgb_, every=False: [])
    found, _ = _largest.largest(matter, rgb)
    assert found[0] is (later if expected == "other" else walked)
