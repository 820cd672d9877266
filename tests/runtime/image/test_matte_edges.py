"""relight_rt.image.matte_edges.refine_edges: alpha re-estimated from colour in a band around a coarse matte's
outline."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from relight_rt.image import matte_edges as R
from relight_rt.image.io import read_image
from relight_rt.person import matting as M


def strands(h: int = 200, w: int = 240):
    """A red person (left) with thin strands reaching into a blue background: the true alpha, the photo, and a
    coarse matte (the true one blurred, as an upsampled segmentation is)."""
    truth = np.zeros((h, w), np.float32)
    truth[:, : w // 2] = 1.0
    for k in range(6):  # strands 2 px wide, 30 px long, sticking out of the edge
        y = 20 + 30 * k
        truth[y : y + 2, w // 2 : w // 2 + 30] = 1.0
    f = np.array([0.9, 0.2, 0.1], np.float32)
    b = np.array([0.1, 0.3, 0.9], np.float32)
    rgb = truth[..., None] * f + (1 - truth[..., None]) * b
    coarse = np.clip(cv2.GaussianBlur(truth, (0, 0), 6.0), 0.0, 1.0)
    return rgb.astype(np.float32), truth, coarse


def test_strands_come_back_where_colour_tells_them_apart():
    rgb, truth, coarse = strands()
    out = R.refine_edges(rgb, coarse, band=10)
    band = cv2.dilate(((coarse > 0.05) & (coarse < 0.95)).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert np.abs(out - truth)[band].mean() < 0.6 * np.abs(coarse - truth)[band].mean()  # measured 0.47x
    assert out.dtype == np.float32 and out.shape == truth.shape and 0 <= out.min() and out.max() <= 1


def test_outside_the_band_the_coarse_matte_is_kept_and_faint_veils_go():
    rgb, _, coarse = strands()
    veiled = coarse.copy()
    veiled[:, -40:] = np.maximum(veiled[:, -40:], 0.1)  # a faint veil over the background, far from the outline
    out = R.refine_edges(rgb, veiled, band=4)
    far = cv2.distanceTransform((coarse < 0.5).astype(np.uint8), cv2.DIST_L2, 5) + cv2.distanceTransform(
        (coarse >= 0.5).astype(np.uint8), cv2.DIST_L2, 5
    )
    kept = (far > 30) & (veiled > 0.2) & (veiled < 0.8)
    np.testing.assert_array_equal(out[kept], veiled[kept])
    assert not out[:, -40:].any()  # the veil would show the old background in a composite


def person_left(person, backdrop, h=120, w=160):
    """(truth, rgb): a person of one colour filling the left half of an (h, w) picture, a plain backdrop right."""
    truth = np.zeros((h, w), np.float32)
    truth[:, : w // 2] = 1.0
    rgb = np.empty((h, w, 3), np.float32)
    rgb[:] = backdrop
    rgb[:, : w // 2] = person
    return truth, rgb


def test_a_light_patch_of_background_in_the_band_fades_out_without_an_edge():
    """A white stripe of background (an awning) beside a red person on a dark background: colour puts it between
    the dark background and the person, so its alpha comes out high; toward the band's outer edge, where the coarse
    matte is sure of background, it must fade to 0 and not end in a step at the band's edge (a straight-edged
    grey patch in every composite: the reference photo's awning beside the hair)."""
    band = 12
    truth, rgb = person_left((0.8, 0.3, 0.2), (0.1, 0.1, 0.1))
    rgb[46:54, 80:] = (0.95, 0.95, 0.95)  # a thin stripe runs from the outline out of the band
    coarse = np.clip(cv2.GaussianBlur(truth, (0, 0), 1.5), 0.0, 1.0)
    out = R.refine_edges(rgb, coarse, band=band)
    row = out[50, 80 : 80 + band + 3]  # across the band, along the stripe
    assert row[band - 2 :].max() < 0.05  # faded out by the band's outer edge: no step there
    assert np.all(np.diff(row[2:]) <= 1e-6)  # falling, not a plateau that ends
    assert out[50, 80 + band // 2] < 0.6


def test_where_colours_are_alike_the_coarse_matte_stays():
    rgb, _, coarse = strands()
    grey = np.full_like(rgb, 0.4)  # no colour difference at all: nothing to go on
    # only the closing 3x3 guided filter acts (on a flat guide: a 3x3 mean): differences of a few thousandths
    mid = (coarse > 0.2) & (coarse < 0.8)  # (faint values are snapped to 0 / 1)
    np.testing.assert_allclose(R.refine_edges(grey, coarse, band=10)[mid], coarse[mid], atol=0.01)


def test_a_part_of_a_third_colour_at_the_outline_keeps_the_coarse_matte():
    """A green belt of the red person's, reaching the outline against a blue backdrop: its colour lies far off the
    line from the backdrop's colour to the person's, so colour cannot say how much of it is person (projected on
    that line it reads about half). The coarse matte is sure of it and stays; without the off-line weight
    (_OFF_LINE) the belt came out at 0.71-0.74 across the band's inner half: a hole showing the old background."""
    band = 8
    truth, rgb = person_left((0.9, 0.2, 0.1), (0.1, 0.3, 0.9))
    rgb[56:64, :80] = (0.1, 0.8, 0.1)
    coarse = np.clip(cv2.GaussianBlur(truth, (0, 0), 1.5), 0.0, 1.0)
    out = R.refine_edges(rgb, coarse, band=band)
    belt, plain = out[58:62, 80 - band : 78], out[28:32, 80 - band : 78]
    assert belt.min() >= 0.9 and np.abs(belt - plain).max() < 0.1  # measured 0.97 (0.71 without)
    assert out[58:62, 80:].max() < 0.85 and out[58:62, 82:].max() == 0.0  # the outline stays where it was


def test_empty_and_full_mattes_unchanged():  # (and only faint values are snapped)
    rgb = np.random.default_rng(0).random((40, 50, 3), dtype=np.float32)
    for a in (np.zeros((40, 50), np.float32), np.ones((40, 50), np.float32)):
        np.testing.assert_array_equal(R.refine_edges(rgb, a), a)


def test_band_width_follows_the_photo():
    assert R.band_width((100, 120)) == 3 and R.band_width((1302, 1950)) == 16


def test_reference_photo_edges_refined(reference_dir):
    """Issue 33: the refinement must not lose overlap with the hand mask and must gain in its soft band."""
    rgb = np.ascontiguousarray(read_image(reference_dir / "photo" / "sample.jpg")[..., :3])
    gt = cv2.imread(str(reference_dir / "photo" / "sample_mask.png"), cv2.IMREAD_GRAYSCALE) / 255.0
    before = M.PersonMatter(edges=False)(rgb)
    after = M.PersonMatter()(rgb)
    iou = lambda a: float(((a >= 0.5) & (gt >= 0.5)).sum() / ((a >= 0.5) | (gt >= 0.5)).sum())  # noqa: E731
    soft = (gt > 0.02) & (gt < 0.98)
    assert iou(after) >= 0.970 and iou(after) >= iou(before) - 1e-3  # measured 0.9713 (before 0.9695)
    assert np.abs(after - gt)[soft].mean() < 0.97 * np.abs(before - gt)[soft].mean()  # measured 0.219 vs 0.237


@pytest.mark.parametrize("edges", [True, False])
def test_video_matter_does_not_refine_the_band(edges):
    vm = M.VideoMatter(M.PersonMatter(edges=edges))
    rgba = read_image(M.bundled_models_dir().parent / "data" / "example.png")
    rgb = np.ascontiguousarray(rgba[..., :3])
    a = vm(rgb)
    assert a.shape == rgb.shape[:2]


def _cut_portrait(h: int = 240, w: int = 200):
    """A red torso running out of the bottom border into a blue background, its coarse matte half sure (0.6) over a
    patch near the bottom (a patterned shirt the graphs doubt) and over one as far up as the head."""
    truth = np.zeros((h, w), np.float32)
    truth[60:, 40:160] = 1.0
    rgb = truth[..., None] * np.array([0.9, 0.2, 0.1], np.float32) + (1 - truth[..., None]) * np.array(
        [0.1, 0.3, 0.9], np.float32
    )
    coarse = np.clip(cv2.GaussianBlur(truth, (0, 0), 3.0), 0.0, 1.0)
    coarse[200:, 100:140] = 0.6  # at the bottom border, inside the body
    coarse[80:100, 80:120] = 0.6  # high up: not where the frame cuts the body
    return rgb.astype(np.float32), coarse


def test_body_cut_by_the_bottom_border_is_opaque_there():
    """DPR's checked shirt stayed at alpha 0.53-0.73 where the frame cut it; a composite showed the new background
    through the body. The doubt near the bottom border goes (was 0.6), the soft outline there stays, and a doubtful
    patch far above the border is not the cut's."""
    rgb, coarse = _cut_portrait()
    out = R.refine_edges(rgb, coarse, band=4)
    assert out[200:, 100:140].min() == 1.0  # was 0.6
    assert out[239, :36].max() < 0.05 and 0.5 < out[239, 40:43].min() < 0.99  # the outline meets the border soft
    # far above the border the patch is not the cut's (refine_edges closes it as a pocket of the person's colour)
    np.testing.assert_allclose(R.opaque_where_cut(coarse.copy(), 4, rgb)[80:100, 80:120], 0.6)


def test_a_patch_just_under_half_where_the_frame_cuts_the_body_is_body_unless_it_is_the_backdrop():
    """DPR's portrait: the graphs left a pale blue collar at 0.47-0.52 where the frame cuts the shirt, the outline
    went round the part under 0.5, and relit it stayed a pale blob. A patch at 0.45 in the body's colour becomes
    opaque; one at 0.45 in the backdrop's colour (a ring around a gap between arm and body) does not."""
    rgb, coarse = _cut_portrait()
    coarse[200:230, 60:90] = 0.45  # the body's red: a doubtful patch of shirt
    rgb[195:235, 105:140] = np.array([0.1, 0.3, 0.9], np.float32)  # a gap showing the blue backdrop ...
    coarse[195:235, 105:140] = 0.45  # ... that the graphs half-see
    coarse[210:220, 118:127] = 0.0  # (its middle they see)
    out = R.refine_edges(rgb, coarse, band=4)
    assert out[205:225, 65:85].min() == 1.0  # was 0.45
    assert out[196:234, 106:139].max() < 0.5  # not made body (colour lowers it further)
    assert R.opaque_where_cut(coarse.copy(), 4)[205:225, 65:85].max() < 0.5  # without the photo: left as it was


def test_a_doubted_blob_the_border_cuts_beside_the_body_is_not_made_opaque():
    """A small portrait: the graphs half-saw the blurred garden (0.5-0.7) where the bottom border cuts it, joined to
    the shoulder's side, and the whole block up to the reach was made opaque. Nothing sure lies above it in its
    columns: it stays as the graphs left it, while the body's own doubted patch beside it is still filled."""
    rgb, coarse = _cut_portrait()
    coarse[185:, :44] = 0.65  # backdrop blue, half-seen, running into the torso's side (columns 40-160)
    out = R.opaque_where_cut(coarse.copy(), 4, rgb)
    np.testing.assert_allclose(out[190:, :30], 0.65)  # was 1.0
    assert out[200:, 100:140].min() == 1.0  # the torso's doubted patch (0.6) still filled


def test_a_separate_part_the_graphs_are_nowhere_sure_of_goes_and_a_sure_one_stays():
    """A small portrait: the selfie graph half-saw blobs of the blurred garden apart from her (0.5-0.7); relit, they
    changed with her and came along into every composite. A part seen apart and sure (a hand beyond a railing)
    stays, and so does the largest part however doubted."""
    h, w = 200, 240
    truth = np.zeros((h, w), np.float32)
    truth[40:, 120:200] = 1.0  # the person
    truth[60:90, 215:235] = 1.0  # a hand seen apart
    rgb = truth[..., None] * np.array([0.9, 0.2, 0.1], np.float32) + (1 - truth[..., None]) * 0.5
    coarse = np.clip(cv2.GaussianBlur(truth, (0, 0), 1.5), 0.0, 1.0)
    coarse[60:120, 20:80] = np.maximum(coarse[60:120, 20:80], 0.65)  # the garden half-seen, in the backdrop's grey
    out = R.without_doubted_parts(R.refine_edges(rgb, coarse, band=4), 4)
    assert out[50:130, 10:90].max() == 0.0  # was 0.65 inside: a blob of garden
    assert out[65:85, 220:230].min() > 0.95 and out[60:, 130:190].min() == 1.0
    doubted = np.where(coarse > 0.5, 0.6, coarse).astype(np.float32)  # every part doubted: the largest stays
    out = R.without_doubted_parts(doubted.copy(), 4)
    assert out[60:, 130:190].min() == 0.6 and out[70:110, 30:70].max() == 0.0


def test_bottom_rows_of_a_body_not_at_the_border_are_left_alone():
    rgb, coarse = _cut_portrait()
    flipped = np.ascontiguousarray(coarse[::-1])  # the torso now runs out of the top: no cut at the bottom
    out = R.opaque_where_cut(flipped.copy(), 4, np.ascontiguousarray(rgb[::-1]))
    np.testing.assert_allclose(out[:40, 100:140], 0.6, atol=0.05)


def test_a_matte_fading_toward_the_bottom_border_is_opaque_there_but_not_below_feet():
    """The graphs' answer fades toward the border where a body runs out of it (zidane's coat: 0.85 -> 0.45 over the
    last 14 rows): it showed a see-through strip along the border. Feet that end above the border get no column
    of body below them (the reference photo's boot: a stripe to the border was the first try's mistake)."""
    rgb, coarse = _cut_portrait()
    coarse[-12:, 40:160] = np.minimum(coarse[-12:, 40:160], np.linspace(0.9, 0.45, 12, dtype=np.float32)[:, None])
    out = R.refine_edges(rgb, coarse, band=4)
    assert out[-12:, 60:140].min() == 1.0  # was 0.45 at the border
    feet = np.zeros((240, 200), np.float32)
    feet[60:234, 80:120] = 1.0  # a leg and boot that end 6 rows above the bottom border
    soft = np.clip(cv2.GaussianBlur(feet, (0, 0), 1.5), 0.0, 1.0)
    out = R.refine_edges(np.repeat(soft[..., None], 3, 2), soft, band=4)
    assert out[237:].max() < 0.05


def _arm_and_body(h: int = 200, w: int = 200):
    """A blue body beside a skin-coloured arm on a white backdrop, a white sliver of backdrop between them that the
    coarse matte half-sees (0.7) as the graphs leave the reference video's arm-dress gaps."""
    truth = np.zeros((h, w), np.float32)
    truth[20:190, 60:130] = 1.0  # body
    truth[40:180, 136:150] = 1.0  # arm, 6 px from the body
    rgb = np.ones((h, w, 3), np.float32)
    rgb[20:190, 60:130] = (0.25, 0.3, 0.6)
    rgb[40:180, 136:150] = (0.75, 0.55, 0.5)
    coarse = np.clip(cv2.GaussianBlur(truth, (0, 0), 2.0), 0.0, 1.0)
    coarse[20:190, 60:150] = np.maximum(coarse[20:190, 60:150], truth[20:190, 60:150])
    coarse[50:170, 130:136] = 0.7  # the sliver, enclosed by body and arm along its length
    return rgb, truth, coarse


def test_a_half_seen_gap_between_arm_and_body_opens():
    rgb, _, coarse = _arm_and_body()
    out = R.refine_edges(rgb, coarse, band=4)
    assert out[60:160, 131:135].max() < 0.5  # the backdrop between them
    assert out[30:180, 70:120].min() == 1.0 and out[50:170, 140:146].min() == 1.0  # body and arm stay


def test_a_matte_riddled_with_pockets_decides_its_largest_and_stays_fast(monkeypatch):
    """fuzz8: every pocket costs a window of the photo (:func:`R._open_gap`), so a matte riddled with them (2,600 at a
    megapixel) took 12 s; real photos and the reference clip have at most 12. The largest _MAX_POCKETS are decided
    while their boxes span at most the matte's (_POCKET_SPAN); the arm's sliver still opens, the rest keep the
    coarse matte."""
    rgb, _, coarse = _arm_and_body(400, 400)
    rgb[220:390, 20:390], coarse[220:390, 20:390] = (0.25, 0.3, 0.6), 1.0  # and a coat below, riddled with specks
    yy, xx = np.mgrid[232:380:10, 32:380:10].reshape(2, -1)
    for y, x in zip(yy, xx, strict=True):
        coarse[y : y + 3, x : x + 3] = 0.7
    calls = []
    gap = R._open_gap
    monkeypatch.setattr(R, "_open_gap", lambda *args: (calls.append(1), gap(*args)))
    out = R.open_pockets(rgb, coarse, band=4)
    assert len(yy) > 2 * R._MAX_POCKETS and len(calls) == R._MAX_POCKETS
    assert out[60:160, 131:135].max() < 0.5  # the sliver, the largest, opens
    # fewer pockets, each as wide as the coat (diagonal seams: 6 s at a megapixel): while their boxes span the matte's
    rgb, _, coarse = _arm_and_body(400, 400)
    rgb[220:390, 20:390], coarse[220:390, 20:390] = (0.25, 0.3, 0.6), 1.0
    yy, xx = np.mgrid[232:378, 32:378]
    coarse[232:378, 32:378][(yy + xx) % 9 == 0] = 0.7
    calls.clear()
    out = R.open_pockets(rgb, coarse, band=4)
    assert 1 < len(calls) < 20  # of 56 seams
    assert out[60:160, 131:135].max() < 0.5


def test_a_soft_pocket_not_in_the_backdrops_colour_is_the_persons():
    """The same pocket in a colour between the body's and the backdrop's (a pale fold of the dress): colour alone
    would put it halfway; it is not the backdrop's colour, so it is the person's, opaque. It kept the graphs' answer
    (0.7) before: relit, a translucent seam of the old photo (people_masks, translucent interior: photos A 1.56 % ->
    1.44 %, B 2.22 % -> 2.02 %, the clip 1.17 % -> 1.01 %, with the gaps _layout.backed_logits leaves in doubt)."""
    rgb, _, coarse = _arm_and_body()
    rgb[50:170, 130:136] = (0.55, 0.6, 0.8)
    out = R.refine_edges(rgb, coarse, band=4)
    assert out[60:160, 131:135].min() == 1.0


def test_a_gap_whose_middle_the_coarse_matte_drops_under_half_is_still_a_pocket():
    """A gap two canvas pixels wide: the coarse matte has its middle under 0.5 (a hole) and its sides at 0.6-0.8
    (the reference clip's arms and dress). As a hole, its own outline took the sides out of the interior and no
    pocket was found: the gap stayed half-held (0.5-0.8). Filled (_deep_inside), it is one pocket and opens."""
    rgb, _, coarse = _arm_and_body()
    coarse[60:160, 132:134] = 0.4
    out = R.refine_edges(rgb, coarse, band=4)
    assert out[60:160, 131:135].max() < 0.3
    assert out[30:180, 70:120].min() == 1.0 and out[50:170, 140:146].min() == 1.0


def test_a_fold_of_the_persons_colour_whose_middle_drops_under_half_is_the_persons():
    """A pale fold of the dress two canvas pixels wide whose coarse middle is under 0.5: filled, it is a pocket of the
    person's colour, opaque; measuring the band from every hole's outline (a real hole's rule) left its sides at
    0.5-0.8, a translucent seam."""
    rgb, _, coarse = _arm_and_body()
    rgb[50:170, 130:136] = (0.55, 0.6, 0.8)
    coarse[60:160, 132:134] = 0.4
    out = R.refine_edges(rgb, coarse, band=4)
    assert out[70:150, 130:132].min() == 1.0 and out[70:150, 134:136].min() == 1.0


def test_a_real_hole_keeps_its_soft_rim():
    """The backdrop seen through a large hole (the crook of an arm on the hip), its edge blurred: the hole holds sure
    background, so it is no gap to fill; filled, its whole soft rim was one pocket of "not the backdrop's colour"
    and went opaque (the rim's error 0.019 -> 0.108, the row across it 1, 1, 1, 1 where the photo fades)."""
    truth = np.zeros((300, 300), np.float32)
    truth[20:290, 40:260] = 1.0
    truth[100:200, 110:190] = 0.0
    soft = cv2.GaussianBlur(truth, (0, 0), 2.0)
    person, back = np.array((0.25, 0.3, 0.6), np.float32), np.array((0.9, 0.9, 0.85), np.float32)
    rgb = (soft[..., None] * person + (1 - soft[..., None]) * back).astype(np.float32)
    coarse = np.clip(cv2.GaussianBlur(truth, (0, 0), 3.0), 0, 1).astype(np.float32)
    out = R.refine_edges(rgb, coarse, band=4)
    rim = (soft > 0.02) & (soft < 0.98)
    rim[:90] = rim[210:] = False
    rim[:, :100] = rim[:, 200:] = False
    assert np.abs(out - soft)[rim].mean() < 0.05
    assert (out[rim] == 1.0).mean() < 0.1
    assert 0.3 < out[150, 109] < 0.9  # the fade across the hole's side, not opaque


def test_a_soft_stretch_along_the_outline_is_not_a_gap():
    """A soft region inside the outline but open to it along its length (the top of a dark cap before a dark flag)
    is the outline's business, not a gap: the colour of the backdrop there does not open it."""
    rgb, truth, coarse = _arm_and_body()
    coarse[50:170, 130:136] = 1.0
    coarse[20:40, 65:125] = 0.7  # a shallow soft stretch along the body's top, from its outline down
    rgb[20:40, 65:125] = 1.0  # in the backdrop's colour
    out = R.refine_edges(rgb, coarse, band=4)
    np.testing.assert_allclose(out[26:38, 75:115], 0.7, atol=0.02)


@pytest.mark.parametrize("rule", [True, False])
def test_a_lighter_streak_of_the_persons_own_colour_stays_opaque(rule, monkeypatch):
    """A pocket the graphs half-hold in a lighter shade of the clothes around it, before a backdrop of nearly that
    colour (p236: beige trousers and jacket folds on beige pavement): each pixel lies within _GAP_MATCH of the
    backdrop, so pixel by pixel it half-opened (1.0 -> 0.53-0.69). The clothes around it pass that test too: colour
    says nothing there, and the pocket is the person's (``_rim_like_backdrop``). Without that test it half-opens."""
    if not rule:
        monkeypatch.setattr(R, "_rim_like_backdrop", lambda *args: False)
    rgb, _, coarse = _arm_and_body()
    rgb[:] = (0.68, 0.64, 0.58)  # pavement
    rgb[20:190, 60:150] = (0.6, 0.55, 0.5)  # trousers: body, arm and what lies between
    rgb[50:170, 130:136] = (0.62, 0.57, 0.52)  # the lighter streak
    out = R.refine_edges(rgb, coarse, band=4)
    streak = out[60:160, 131:135]
    assert (streak.min() == 1.0) == rule
    if not rule:
        assert streak.min() < 0.8
    assert out[30:180, 70:120].min() == 1.0 and out[50:170, 140:146].min() == 1.0
