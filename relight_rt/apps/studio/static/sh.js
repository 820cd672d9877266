// Spherical-harmonics lights for the studio page: the same numbers as relight_rt/light/sh.py and
// relight_rt/light/presets.py (DESIGN.md §3), checked against them by tests/runtime/apps/studio/test_studio.py.
//
// Frame: +x from the subject toward the camera, +y toward the image's right, +z up.
// Basis: real, orthonormal, degree 2, order 1, y, z, x, xy, yz, 3z²−1, xz, x²−y² (times constants).
// A light is a flat array of 27 numbers, index 3k + c: coefficient k of colour c (R, G, B), i.e. the
// (9, 3) array of the Python side, row-major.

export const C0 = 1 / (2 * Math.sqrt(Math.PI));
export const C1 = Math.sqrt(3 / (4 * Math.PI));
export const C2 = Math.sqrt(15 / Math.PI) / 2;
export const C20 = Math.sqrt(5 / Math.PI) / 4;
export const C22 = Math.sqrt(15 / Math.PI) / 4;
export const BAND = [0, 1, 1, 1, 2, 2, 2, 2, 2];
// zonal coefficients of the clamped cosine, per band: π, 2π/3, π/4
export const LOBE = [Math.PI, (2 * Math.PI) / 3, Math.PI / 4];
export const LUMA = [0.2126, 0.7152, 0.0722];

export function basis(x, y, z) {
  return [C0, C1 * y, C1 * z, C1 * x, C2 * x * y, C2 * y * z, C20 * (3 * z * z - 1), C2 * x * z, C22 * (x * x - y * y)];
}

export function zeros() {
  return new Array(27).fill(0);
}

export function add(a, b) {
  return a.map((v, i) => v + b[i]);
}

export function scale(a, s) {
  return a.map((v) => v * s);
}

function normalise(d) {
  const n = Math.hypot(d[0], d[1], d[2]);
  if (!(n > 1e-12)) throw new Error("direction: expected a non-zero vector");
  return [d[0] / n, d[1] / n, d[2] / n];
}

// Per-band zonal factors of a uniform cap of half-angle a (lights._cap_zonal).
function capZonal(cosA) {
  return [1, (1 + cosA) / 2, (cosA * (1 + cosA)) / 2];
}

// lights.directional: a lamp of angular radius `radius` (radians) from `direction`; a diffuse surface
// facing it receives irradiance intensity · color.
export function directional(direction, color, intensity, radius) {
  const d = normalise(direction);
  const g = capZonal(Math.cos(radius));
  const y = basis(d[0], d[1], d[2]);
  let facing = 0;
  for (let k = 0; k < 9; k++) facing += LOBE[BAND[k]] * g[BAND[k]] * y[k] * y[k];
  const out = zeros();
  for (let k = 0; k < 9; k++) {
    const w = ((intensity / facing) * g[BAND[k]] * y[k]);
    for (let c = 0; c < 3; c++) out[3 * k + c] = w * color[c];
  }
  return out;
}

// lights.ambient: every normal receives irradiance `color`.
export function ambient(color) {
  const out = zeros();
  for (let c = 0; c < 3; c++) out[c] = color[c] / (Math.PI * C0);
  return out;
}

// sh.rotate_z: turn the environment by `angle` radians about +z, carrying +x toward +y.
export function rotateZ(light, angle) {
  const c1 = Math.cos(angle), s1 = Math.sin(angle), c2 = Math.cos(2 * angle), s2 = Math.sin(2 * angle);
  const out = light.slice();
  for (let c = 0; c < 3; c++) {
    const k = (i) => light[3 * i + c];
    out[3 * 3 + c] = c1 * k(3) - s1 * k(1);
    out[3 * 1 + c] = s1 * k(3) + c1 * k(1);
    out[3 * 7 + c] = c1 * k(7) - s1 * k(5);
    out[3 * 5 + c] = s1 * k(7) + c1 * k(5);
    out[3 * 8 + c] = c2 * k(8) - s2 * k(4);
    out[3 * 4 + c] = s2 * k(8) + c2 * k(4);
  }
  return out;
}

// sh.irradiance at one unit normal: [r, g, b].
export function irradiance(light, n) {
  const y = basis(n[0], n[1], n[2]);
  const e = [0, 0, 0];
  for (let k = 0; k < 9; k++) {
    const w = LOBE[BAND[k]] * y[k];
    for (let c = 0; c < 3; c++) e[c] += w * light[3 * k + c];
  }
  return e;
}

// The lamp sphere widget. (u, v): position in units of the sphere's radius, u toward the image's right,
// v up. Inside the disc (ρ <= 1) it is the sphere's visible point (x = sqrt(1 − ρ²)); the ring
// 1 < ρ <= rhoMax holds the hemisphere behind the subject, polar angle from +x growing linearly
// from 90° at the disc's edge to 180° at the ring's outer edge.
export function widgetToDirection(u, v, rhoMax) {
  const rho = Math.hypot(u, v);
  if (rho <= 1) return [Math.sqrt(Math.max(0, 1 - rho * rho)), u, v];
  const r = Math.min(rho, rhoMax);
  const theta = Math.PI / 2 + ((r - 1) / (rhoMax - 1)) * (Math.PI / 2);
  const s = Math.sin(theta) / rho;
  return [Math.cos(theta), u * s, v * s];
}

export function directionToWidget(d, rhoMax) {
  const [x, y, z] = normalise(d);
  if (x >= 0) return [y, z];
  const theta = Math.acos(Math.max(-1, Math.min(1, x)));
  const rho = 1 + ((theta - Math.PI / 2) / (Math.PI / 2)) * (rhoMax - 1);
  const t = Math.hypot(y, z);
  if (t < 1e-9) return [0, rho];
  return [(rho * y) / t, (rho * z) / t];
}

// The exposure rule of the final result (DESIGN.md §3, relight_rt.light.exposure.exposure_scale): the scalar s for
// which the light s · L gives the person the mask-weighted power mean of the Rec. 709 luminance Y of
// albedo ⊙ max(0, T·L), (mean Y^power)^(1/power), target · 2^ev (power 2.2: the light as seen of encoded values,
// relight_rt.light.exposure.METER_POWER; 1: the plain mean). layers: the exposure sample of the layers (decodeLayers:
// {transport: 9 Float32Array planes, albedo: 3 planes (the network's, masked), mask}); every `step`-th pixel is
// used (the page uses step 1).
export function exposureScale(layers, light, target, ev, step, power = 1) {
  const T = layers.transport, A = layers.albedo, M = layers.mask;
  const n = M.length;
  let sum = 0, msum = 0;
  for (let p = 0; p < n; p += step) {
    msum += M[p];
    let y = 0;
    for (let c = 0; c < 3; c++) {
      let s = 0;
      for (let k = 0; k < 9; k++) s += T[k][p] * light[3 * k + c];
      if (s > 0) y += LUMA[c] * A[c][p] * s;
    }
    sum += M[p] * (power === 1 ? y : Math.pow(Math.max(y, 0), power));
  }
  const mean = sum / Math.max(msum, 1e-6);
  const current = power === 1 ? mean : Math.pow(mean, 1 / power);
  const gain = Math.pow(2, ev);
  return current > 1e-8 && target > 1e-8 ? (gain * target) / current : gain;
}

// The background grade of the final result (relight_rt.relight.compose.background_grade: the person's change in
// light per channel, relit over own, each decoded from sRGB and summed with the matte's weight; the backdrop's
// values times its 1 / gamma power) on its sample (relight_rt.relight.compose.sampled_grade): pixel p relit is
// lit · S + steady · S / Y(S), blended toward the head pass's where it has one (headLevel), where the photo is a
// near-neutral dark its chroma kept (neutralStep), its brightest channel rolled off past its knee (the highlight
// shoulder, as shoulderGain), against its own colour (the own sums are kept on `sample`). Returns the gain per
// channel on the backdrop's values.
export function backgroundGrade(sample, light, gamma) {
  const T = sample.transport, lit = sample.lit, steady = sample.steady, w = sample.weight, q = sample.knee;
  const n = w.length, head = sample.head, nb = head ? head.index.length : 0;
  if (!sample.ownSum) {  // the own colour's sums and the matte's, once per sample
    sample.ownSum = [0, 0, 0];
    sample.weightSum = 0;
    for (let p = 0; p < n; p++) {
      for (let c = 0; c < 3; c++) sample.ownSum[c] += w[p] * srgbToLinear(sample.own[c][p]);
      sample.weightSum += w[p];
    }
  }
  const level = nb ? headLevel(sample, light) : 1, kept = sample.headKept;
  const was = sample.ownSum, now = [0, 0, 0], S = [0, 0, 0], v = [0, 0, 0];
  for (let p = 0, k = 0; p < n; p++) {
    let peak = -Infinity;
    if (k < nb && head.index[k] === p) {  // the head pass's factor at the body's level, blended in (headLevel kept
      const b = head.weight[k];  // the body's shading and colour here, and the head pass's colour)
      for (let c = 0; c < 3; c++) {
        S[c] = kept[9 * k + c];
        v[c] = kept[9 * k + 3 + c];
        v[c] += b * (level * kept[9 * k + 6 + c] - v[c]);
      }
      k++;
    } else {
      const y = shadingAt(T, p, light, S);
      for (let c = 0; c < 3; c++) v[c] = Math.max(lit[c][p] * S[c] + (steady[c][p] * S[c]) / y, 0);
    }
    if (sample.neutral && sample.neutral[p] > 0) neutralStep(sample, p, v, S);
    for (let c = 0; c < 3; c++) peak = Math.max(peak, v[c]);
    const s = shoulderScale(peak, q[p]);
    for (let c = 0; c < 3; c++) now[c] += w[p] * srgbTabled(v[c] * s);
  }
  const floor = 1e-6 * Math.max(sample.weightSum, 1);
  return now.map((v, c) => (was[c] > floor ? Math.pow(v / was[c], 1 / gamma) : 1));
}

// The head pass's blend on the grade's sample (relight_rt.relight.compose.head_level; Factor.blend_head): on its
// pixels the body's shading S and colour lit · S + steady · S / Y(S), and the colour under the head pass's factor,
// own · (scale · S' + stays · S' / Y(S')) with S' its shading, into sample.headKept (9 per pixel); returns the level
// that factor is scaled to, the body's factor's luminance (bodyScale · Y(S) + bodyStays) over the head pass's
// (scale · Y(S') + stays), each summed with the skin's weight.
function headLevel(sample, light) {
  const head = sample.head, own = sample.own, lit = sample.lit, steady = sample.steady, nb = head.index.length;
  const out = sample.headKept = sample.headKept ?? new Float64Array(9 * nb);
  const S = [0, 0, 0], H = [0, 0, 0];
  let body = 0, seen = 0;
  for (let k = 0; k < nb; k++) {
    const p = head.index[k];
    const y = shadingAt(sample.transport, p, light, S), yHead = shadingAt(head.transport, k, light, H);
    for (let c = 0; c < 3; c++) {
      out[9 * k + c] = S[c];
      out[9 * k + 3 + c] = Math.max(lit[c][p] * S[c] + (steady[c][p] * S[c]) / y, 0);
      out[9 * k + 6 + c] = own[c][p] * (head.scale[k] * H[c] + (head.stays[k] * H[c]) / yHead);
    }
    if (head.skin[k] > 0) {
      body += head.skin[k] * (head.bodyScale[k] * y + head.bodyStays[k]);
      seen += head.skin[k] * (head.scale[k] * yHead + head.stays[k]);
    }
  }
  return body / Math.max(seen, 1e-6);
}

// The near-neutral darks' rule (relight_rt.relight.look.neutral_values) on sample pixel p, in place on its relit
// colour v (3 numbers) relit by a gain of the colour of S: where the light brightens it, its colour without the
// light's, at its luminance Y', keeps the own colour's chroma direction c = (P - Y) / Y and at most its length x
// (Y / Y')^e (nor more than it has), blended by the pixel's weight and by how much brighter Y' is than Y (none below
// lift[0] x, all from lift[1] x); the light's colour put back.
function neutralStep(sample, p, v, S) {
  const own = sample.own, lift = sample.neutralLift, tint = NEUTRAL_TINT, off = NEUTRAL_OFF;
  const r = own[0][p], g = own[1][p], b = own[2][p];
  const yOwn = LUMA[0] * r + LUMA[1] * g + LUMA[2] * b, y0 = Math.max(yOwn, 1e-6);
  if (!(LUMA[0] * v[0] + LUMA[1] * v[1] + LUMA[2] * v[2] > y0)) return;  // only what the light brightens
  if (!(S[0] > 1e-4 && S[1] > 1e-4 && S[2] > 1e-4)) return;  // ... with some of every channel
  const d = Math.max(yOwn, 1e-3), c0 = (r - yOwn) / d, c1 = (g - yOwn) / d, c2 = (b - yOwn) / d;
  const size = Math.max(Math.sqrt(c0 * c0 + c1 * c1 + c2 * c2), 1e-6);
  const gl = LUMA[0] * S[0] + LUMA[1] * S[1] + LUMA[2] * S[2];
  let y1 = 0;
  for (let i = 0; i < 3; i++) {
    tint[i] = gl > 1e-4 && S[i] > 1e-4 ? S[i] / gl : 1;
    off[i] = v[i] / tint[i];  // the relit colour as a white light of the gain's brightness would give it
    y1 += LUMA[i] * off[i];
  }
  y1 = Math.max(y1, 1e-6);
  let len = 0;
  for (let i = 0; i < 3; i++) {
    off[i] = off[i] / y1 - 1;
    len += off[i] * off[i];
  }
  const keep = Math.min(Math.pow(y0 / y1, sample.neutralChromaExp), 1, Math.sqrt(len) / size);
  const blend = Math.min(Math.max((y1 / y0 - lift[0]) / (lift[1] - lift[0]), 0), 1) * sample.neutral[p] * y1;
  v[0] += tint[0] * blend * (c0 * keep - off[0]);
  v[1] += tint[1] * blend * (c1 * keep - off[1]);
  v[2] += tint[2] * blend * (c2 * keep - off[2]);
}
const NEUTRAL_TINT = [1, 1, 1], NEUTRAL_OFF = [0, 0, 0];  // neutralStep's scratch

// The highlight shoulder's scale on a pixel whose brightest channel is `peak` with its knee `knee`
// (relight_rt.relight.look.shoulder): 1 up to the knee, past it the peak rolled off toward 1, over the peak.
function shoulderScale(peak, knee) {
  return peak > knee ? (knee + (1 - knee) * -Math.expm1(-(peak - knee) / (1 - knee))) / peak : 1;
}

// Pixel p's RGB shading max(0, T·L) into S (3 numbers); returns its luminance, at least 1e-4.
function shadingAt(T, p, light, S) {
  for (let c = 0; c < 3; c++) {
    let s = 0;
    for (let k = 0; k < 9; k++) s += T[k][p] * light[3 * k + c];
    S[c] = Math.max(s, 0);
  }
  return Math.max(LUMA[0] * S[0] + LUMA[1] * S[1] + LUMA[2] * S[2], 1e-4);
}

// sRGB's decoding curve (relight_rt.image.color.srgb_to_linear) of a value clipped to [0, 1].
export function srgbToLinear(v) {
  const x = Math.min(Math.max(v, 0), 1);
  return x <= 0.04045 ? x / 12.92 : Math.pow((x + 0.055) / 1.055, 2.4);
}

// srgbToLinear read from a table of DECODE_STEPS steps, linearly interpolated (within 1e-7 of it): the background
// grade decodes three values a sample pixel each frame, and Math.pow there took half of its time.
const DECODE_STEPS = 4096, DECODE = new Float64Array(DECODE_STEPS + 2);
for (let i = 0; i < DECODE.length; i++) DECODE[i] = srgbToLinear(i / DECODE_STEPS);
export function srgbTabled(v) {
  const x = (v > 0 ? (v < 1 ? v : 1) : 0) * DECODE_STEPS, i = x | 0;
  return DECODE[i] + (x - i) * (DECODE[i + 1] - DECODE[i]);
}

// The exposure's highlight guard (relight_rt.light.exposure.highlight_factor): how much "auto" lowers the exposed light
// so that at most `allowed` of the person goes past `limit` (white), by at most the factor `maxDown`. guard: the
// highlight sample of the layers (decodeLayers: {lit: 3 planes, steady: 3 planes, transport: 9 planes}); pixel p
// under s · light is s · lit · S + steady · S / Y(S) (S its RGB shading, Y the luminance), past white from the
// scale at which its brightest channel reaches the limit.
export function highlightFactor(guard, light, limit, allowed, maxDown) {
  const T = guard.transport, lit = guard.lit, steady = guard.steady;
  const n = lit[0].length;
  if (n === 0) return 1;
  const reach = new Float32Array(n);
  const S = [0, 0, 0];
  for (let p = 0; p < n; p++) {
    const y = shadingAt(T, p, light, S);
    let r = Infinity;
    for (let c = 0; c < 3; c++) {
      const fixed = (steady[c][p] * S[c]) / y, scaled = lit[c][p] * S[c];
      if (fixed >= limit) r = 0;
      else if (scaled > 0) r = Math.min(r, (limit - fixed) / scaled);
    }
    reach[p] = r;
  }
  reach.sort();
  const k = Math.min(Math.floor(Math.min(Math.max(allowed, 0), 1) * n), n - 1);
  return Math.min(Math.max(reach[k], maxDown), 1);
}

// The shoulder's loss given back (relight_rt.light.exposure.shoulder_gain): how much "auto" raises the exposed light
// so that the picture, its highlights rolled off toward white (relight_rt.relight.look.shoulder: past a pixel's knee
// q, its brightest channel m goes to q + (1 - q)(1 - exp(-(m - q) / (1 - q)))), keeps the power mean of luminance
// ** power it had before the shoulder. guard: the highlight sample (as highlightFactor); a pixel's knee is its own
// peak in the photo, lit · Y(W) + steady (W the shading of the photo's own light, white: ownWhite, 9 numbers),
// within knee = [lo, hi]; the gain k, at most maxUp, has seen(k) within tol (log ratio) of the target.
export function shoulderGain(guard, light, ownWhite, knee, maxUp, power, tol, samples) {
  const T = guard.transport, lit = guard.lit, steady = guard.steady;
  const all = lit[0].length;
  if (all === 0) return 1;
  const step = Math.max(1, Math.ceil(all / samples));  // every step-th pixel, at most `samples` (as Python)
  const n = Math.ceil(all / step);
  const a = [new Float64Array(n), new Float64Array(n), new Float64Array(n)];
  const b = [new Float64Array(n), new Float64Array(n), new Float64Array(n)];
  const q = new Float64Array(n);
  const S = [0, 0, 0];
  let target = 0, over = false;
  for (let p = 0; p < n; p++) {
    const i = p * step;
    const y = shadingAt(T, i, light, S);
    let w = 0;
    for (let k = 0; k < 9; k++) w += T[k][i] * ownWhite[k];
    w = Math.max(w, 0);
    let peak = -Infinity, now = -Infinity, lum = 0;
    for (let c = 0; c < 3; c++) {
      a[c][p] = lit[c][i] * S[c];
      b[c][p] = (steady[c][i] * S[c]) / y;
      peak = Math.max(peak, lit[c][i] * w + steady[c][i]);
      now = Math.max(now, a[c][p] + b[c][p]);
      lum += LUMA[c] * (a[c][p] + b[c][p]);
    }
    q[p] = Math.min(Math.max(peak, knee[0]), knee[1]);
    if (now > q[p]) over = true;
    target += Math.pow(Math.max(lum, 0), power);
  }
  if (!over) return 1;  // nothing past its knee: the shoulder takes nothing
  const seen = (k) => {
    let sum = 0;
    for (let p = 0; p < n; p++) {
      let peak = -Infinity, lum = 0;
      for (let c = 0; c < 3; c++) {
        const v = k * a[c][p] + b[c][p];
        peak = Math.max(peak, v);
        lum += LUMA[c] * v;
      }
      lum *= shoulderScale(peak, q[p]);
      sum += Math.pow(Math.max(lum, 0), power);
    }
    return sum;
  };
  // the secant on log seen against log k from k = 1 (relight_rt.light.exposure.shoulder_gain, step for step)
  const logRatio = (now) => (now > 0 && target > 0 ? Math.log(now / target) : target > 0 ? -Infinity : 0);
  const top = Math.log(maxUp);
  let x0 = 0, f0 = logRatio(seen(1));
  if (f0 >= -tol) return 1;  // a loss under tol of the light seen is none (the photo's own pixels at white)
  let x1 = Math.min(-f0 / power, top);
  let f1 = logRatio(seen(Math.exp(x1)));
  for (let i = 0; i < 8; i++) {
    if (Math.abs(f1) < tol || (x1 >= top && f1 < 0)) break;
    const x2 = f1 !== f0 ? x1 - (f1 * (x1 - x0)) / (f1 - f0) : x1 - f1 / power;
    x0 = x1; f0 = f1;
    x1 = Math.min(Math.max(x2, 0), top);
    f1 = logRatio(seen(Math.exp(x1)));
  }
  return Math.exp(x1);
}
