"""The deep shadow's colour: that of the lit pixels around of the shadow's own material.

Where the photo's own shading is near zero the relighting factor adds the new light's change instead of multiplying the
photo (relight_rt.relight.shadow_fill ``ShadowFill.shadow_weight``, relight_rt.relight.factor ``Factor.gain_and_fill``).
The change is added in the person's colour there at luminance 1, which a black shadow does not show: it is read off the
lit (trusted) pixels around. A plain mean over the pixels around mixes materials: a girl's dark hair in shade above a
lit green shirt took the shirt's green (a real photo under ``front``: 0.6 % of its untinted near-black pixels turned
teal, 1.2 % of its grey ones; none with the fill off).

``material_colour`` weighs each lit pixel around by how like the shadow's own material it is: the chromaticity of stage
1's albedo (log R / G, log B / G). Stage 1 reads a material from its context, so its albedo's colour in a shadow is
the material's even where its lightness is not (it takes part of a shadow for a dark albedo: a shaded cheek and dark
hair both come out dark, the hair in shade above the shirt came out as light as the lit cheek), so lightness is left
out; and where stage 1's colour is off (green for fair skin), it is off alike in the lit and the shaded part of the
same material, which is all the weighing asks. The colour taken is still the photo's own, of those lit pixels.

The weighing is a bilateral grid (Chen, Paris and Durand 2007) over that chromaticity alone: each pixel's share in
cells ``MATERIAL_STEP`` apart (a tent, the cells' weights summing to 1), each cell's lit colour and luminance blurred
over the person, and each pixel reading back the cells it shares. A material with no lit pixel near takes that
material's colour over the whole person (``MATERIAL_PRIOR``), and one lit nowhere stays white (the light's colour
alone), as a shadow far from every lit pixel did before.

A pixel on the border between two materials votes little (``_pure``): where it straddles a shadow's edge its albedo
mixes the two materials but its photo is the lit one's alone (the shadow's part adds next to nothing), so it put the
lit neighbour's colour into the shadow's own cell. Whether a network pixel straddles the edge, and how much of it, is
where the network's grid falls (test_fill_colour's strips: the black shadow green or grey by the person's top row).
At the reduced size each cell's material is read as the lit pixels' own (the albedo weighed as the colour is), for
the same reason one size up.
"""

from __future__ import annotations

import cv2
import numpy as np

MATERIAL_STEP = 0.25  # the cells' spacing in log R / G and log B / G of stage 1's albedo (skin 0.35 / -0.2 apart from
# a pale green shirt's -0.1 / -0.25: two cells)
MATERIAL_SPAN = 1.5  # ... chromaticities past this are held to it (a saturated cloth: one of the outer cells)
MATERIAL_FLOOR = 0.02  # ... each albedo channel floored here first (a black albedo reads grey)
MATERIAL_PRIOR = 1e-3  # ... a cell's colour over the whole person counts as this share of the lit person's luminance
MATERIAL_MIXED = 0.125  # ... a lit pixel whose chromaticity is this far from a neighbour's (on either axis) votes
# nothing, half of it fully: a pixel straddling a border mixes the two materials' albedos (not their photos), so it is
# at least half their distance from a neighbour; materials a cell apart (skin and grey: 0.28) are told apart
MATERIAL_KNOWN = 0.01  # ... that colour leaning toward white as if this share of the lit person's luminance were white
# (a material that only a few pixels show lit, say a matte's edge, is not known over the person)
_BATCH = 32  # cells blurred in one call (4 channels each: OpenCV 5 takes at most 128 channels)


def lit_colour(rgb: np.ndarray, luma: np.ndarray, trust: np.ndarray, albedo: np.ndarray | None,
               sigma: float) -> np.ndarray:
    """``material_colour``, or with ``albedo`` None every material alike (the rule before fill31): the colour at
    luminance 1 of the trusted pixels around, white where none is near."""
    if albedo is not None:
        return material_colour(rgb, luma, trust, albedo, sigma)
    num = cv2.GaussianBlur(rgb * trust[..., None], (0, 0), sigma)
    den = cv2.GaussianBlur(luma * trust, (0, 0), sigma)[..., None]
    # luminance 1 already: luma is the Rec. 709 luminance of rgb, and the blur is linear
    return np.divide(num, den, out=np.ones_like(num), where=den > 1e-4).astype(np.float32)


def material_colour(rgb: np.ndarray, luma: np.ndarray, trust: np.ndarray, albedo: np.ndarray,
                    sigma: float) -> np.ndarray:
    """(r, r', 3) float32: around each pixel, the colour at luminance 1 of the trusted pixels of its own material.

    Args:
        rgb: (r, r', 3) the photo (network frame), float32 RGB in [0, 1].
        luma: (r, r') its Rec. 709 luminance.
        trust: (r, r') in [0, 1], the pixels whose colour is read (lit, the person's).
        albedo: (r, r', 3) stage 1's albedo there, unpremultiplied (its chromaticity is the material).
        sigma: the blur's Gaussian over the person, in pixels.
    """
    h, w = luma.shape
    full_uv = _chroma(albedo)
    weight = trust.astype(np.float32) * _pure(full_uv)
    total = float((luma * weight).sum())
    if total <= 1e-6:  # nothing lit to read: white (the light's colour alone)
        return np.ones((h, w, 3), np.float32)
    eps = np.float32(MATERIAL_PRIOR * total / float(weight.sum()))
    lit = np.dstack([rgb * weight[..., None], luma * weight]).astype(np.float32)
    # the cells are filled and blurred at a reduced size (the Gaussian there at least 2 px; as relight.shadow_rim's
    # colour gate does), each pixel's material read at that size too; each pixel reads its cells back at its own
    step = int(min(max(sigma // 2, 1), 4))
    small = cv2.resize(lit, None, fx=1 / step, fy=1 / step, interpolation=cv2.INTER_AREA) if step > 1 else lit
    known = MATERIAL_KNOWN * float(small[..., 3].sum())
    small_uv = full_uv
    if step > 1:  # each reduced pixel's material that of its lit pixels, weighed as their colour is
        votes = cv2.resize(np.dstack([albedo * lit[..., 3:], lit[..., 3]]), small.shape[1::-1],
                           interpolation=cv2.INTER_AREA)
        plain = cv2.resize(albedo, small.shape[1::-1], interpolation=cv2.INTER_AREA)  # (no lit pixel: no vote)
        small_uv = _chroma(np.where(votes[..., 3:] > 1e-6, votes[..., :3] / np.maximum(votes[..., 3:], 1e-6), plain))
    (su, sv), (fu, fv) = _tents(small_uv), _tents(full_uv)
    cells = [(i, j) for i in sorted(set(su) & set(fu)) for j in sorted(set(sv) & set(fv))]
    # white (the light's colour alone) at the prior's weight, which every lit cell's colour over the person replaces
    acc = np.dstack([np.full((h, w, 3), eps, np.float32), np.full((h, w), eps, np.float32)])
    for start in range(0, len(cells), _BATCH):  # the cells' four channels side by side: one blur for a batch
        batch = cells[start : start + _BATCH]
        shares = np.dstack([su[i] * sv[j] for i, j in batch])
        parts = (small[:, :, None, :] * shares[..., None]).reshape(*small.shape[:2], 4 * len(batch))
        sums = parts.reshape(-1, len(batch), 4).sum(axis=0, dtype=np.float64)
        around = cv2.GaussianBlur(parts, (0, 0), sigma / step).reshape(*small.shape[:2], len(batch), 4)
        # each cell's colour over the person (luminance 1), leaning toward white as far as few lit pixels show it
        prior = (sums[:, :3] + known) / (sums[:, 3:] + known)
        around[..., :3] += (eps * (prior - 1)).astype(np.float32)
        around = np.ascontiguousarray(around.transpose(2, 0, 1, 3))  # cell by cell (at the reduced size: cheap)
        for k, (i, j) in enumerate(batch):
            if sums[k, 3] <= 1e-6:  # lit nowhere: white
                continue
            cell = cv2.resize(around[k], (w, h), interpolation=cv2.INTER_LINEAR) if step > 1 else around[k]
            # (cv2's products: numpy's (h, w, 1) x (h, w, 4) broadcast costs several times as much)
            cv2.add(acc, cv2.multiply(cell, cv2.merge([fu[i] * fv[j]] * 4)), dst=acc)
    return (acc[..., :3] / acc[..., 3:]).astype(np.float32)


def _chroma(albedo: np.ndarray) -> np.ndarray:
    """(h, w, 2) float32: log R / G and log B / G of ``albedo`` (floored at ``MATERIAL_FLOOR``, held to
    ``MATERIAL_SPAN``), in cells (``MATERIAL_STEP``)."""
    a = np.maximum(albedo.astype(np.float32), np.float32(MATERIAL_FLOOR))
    return np.clip(np.log(a[..., [0, 2]] / a[..., 1:2]), -MATERIAL_SPAN, MATERIAL_SPAN) / np.float32(MATERIAL_STEP)


def _pure(uv: np.ndarray) -> np.ndarray:
    """(h, w) float32 in [0, 1]: how far each pixel's vote counts, 1 where its chromaticity ``uv`` (``_chroma``) is
    within half ``MATERIAL_MIXED`` of each of its eight neighbours' on both axes, 0 where it is ``MATERIAL_MIXED``
    from one of them (a pixel on a border between materials)."""
    ring = np.ones((3, 3), np.uint8)
    apart = np.maximum(cv2.dilate(uv, ring) - uv, uv - cv2.erode(uv, ring)).max(axis=-1)
    limit = np.float32(MATERIAL_MIXED / MATERIAL_STEP)  # in cells, as uv
    return np.clip(2 - 2 * apart / limit, 0, 1).astype(np.float32)


def _tents(uv: np.ndarray) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """Each pixel's share in the material cells (``material_colour``) along each axis of ``uv`` (``_chroma``):
    {i: (h, w) float32 share}, a tent (a pixel's shares along an axis sum to 1; its share in cell (i, j) is the
    product), only the cells some pixel has a share in."""
    lo = np.floor(uv).astype(np.int32)
    frac = (uv - lo).astype(np.float32)
    tents: tuple[dict[int, np.ndarray], dict[int, np.ndarray]] = ({}, {})
    for axis in (0, 1):
        cell, part = lo[..., axis], frac[..., axis]
        zero = np.zeros_like(part)
        for i in range(int(cell.min()), int(cell.max()) + 2):
            share = np.where(cell == i, 1 - part, np.where(cell == i - 1, part, zero))
            if share.any():
                tents[axis][i] = share
    return tents
