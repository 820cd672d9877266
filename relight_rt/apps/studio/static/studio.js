// The studio page: light panel, live preview while dragging, full result from the server on release.
import * as sh from "./sh.js";
import { createPreview, decodeLayers } from "./preview.js";
import { ZoomView, facePoint } from "./view.js";

const $ = (id) => document.getElementById(id);
const RHO_MAX = 1.3;  // outer edge of the "behind" ring, in sphere radii

const state = {
  info: null,
  layers: null,
  preview: null,
  lamp: { on: true, direction: [0.75, 0.45, 0.5], colour: [1, 0.957, 0.902], intensity: 1, size: 20 },
  ambient: 0.15,
  base: { name: "none", light: sh.zeros(), rotate: 0, level: 1 },
  exposure: { mode: "auto", ev: 0, byPreset: 0 },
  seq: 0,          // the light's version; a full result is shown only for the version it was made for
  result: null,    // {id, seq, ...} of the latest full result
  dirty: false,
  pendingInput: null,  // timeStamp of the first input event not yet painted
  stats: { frames: 0, latencies: [], frameTimes: [] },  // frameTimes: the latest frames drawn for the user's input
  view: null,      // the ZoomView of the photo area
  before: false,   // the original photo is shown (while the before key or button is held)
  shadow: null,    // the faces' cast shadows of the final result for one light: {key, plane, meter} (fetchShadow)
  shadowBusy: false,
  shadowPending: false,  // a light settled while a shadow request was on its way
};

// ------------------------------------------------------------------------------------------------ light

function hexToRgb(hex) {
  const v = parseInt(hex.slice(1), 16);
  return [((v >> 16) & 255) / 255, ((v >> 8) & 255) / 255, (v & 255) / 255];
}

// The light the user has set, before exposure: base (turned, scaled) + lamp + ambient; 27 numbers RGB.
export function composedLight() {
  let light = sh.scale(sh.rotateZ(state.base.light, (state.base.rotate * Math.PI) / 180), state.base.level);
  const lamp = state.lamp;
  if (lamp.on && lamp.intensity > 0) {
    light = sh.add(light, sh.directional(lamp.direction, lamp.colour, lamp.intensity, (lamp.size * Math.PI) / 180));
  }
  if (state.ambient > 0) light = sh.add(light, sh.ambient([state.ambient, state.ambient, state.ambient]));
  return light.map((v) => Math.fround(v));  // float32, as the server and the light files hold it
}

function exposureValue() {
  const e = state.exposure;
  return e.mode === "physical" ? "physical" : e.mode === "ev" ? e.ev : "auto";
}

// The faces' cast shadows the final result puts under `light` and its head pass's change (the server's, Studio.shadow),
// when they are known for that light: {key, plane (the factor on the preview's shading, height x width), meter (the
// exposure's lift)}.
function shadowFor(light) {
  const key = light.join(",");
  return state.shadow && state.shadow.key === key ? state.shadow : null;
}

// Ask the server for the cast shadows of the light the user has set, once it has settled (on release, as the full
// result): one request at a time; a light that settles while one is on its way is asked for after it. The answer is
// drawn only for its own light.
async function fetchShadow() {
  if (state.shadowBusy) {
    state.shadowPending = true;
    return;
  }
  state.shadowBusy = true;
  try {
    do {
      state.shadowPending = false;
      const light = composedLight();
      const key = light.join(",");
      if (state.shadow && state.shadow.key === key) continue;
      const res = await api("/api/shadow", {
        method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify({ light }),
      });
      const out = await res.json();
      const { width: w, height: h } = state.layers;
      let plane = null;
      if (out.box.length === 4) {
        const [y0, y1, x0, x1] = out.box, bw = x1 - x0;
        const depth = Uint8Array.from(atob(out.depth), (c) => c.charCodeAt(0));
        plane = new Float32Array(w * h).fill(1);
        for (let y = y0; y < y1; y++) {
          for (let x = x0; x < x1; x++) plane[y * w + x] = 1 - depth[(y - y0) * bw + (x - x0)] / 255;
        }
      }
      // the head pass's change of the person's luminance (float32 little-endian over its box), on the same plane
      if (out.head_box && out.head_box.length === 4) {
        const [y0, y1, x0, x1] = out.head_box, bw = x1 - x0;
        const bytes = Uint8Array.from(atob(out.head), (c) => c.charCodeAt(0));
        const change = new DataView(bytes.buffer);
        plane = plane ?? new Float32Array(w * h).fill(1);
        for (let y = y0; y < y1; y++) {
          for (let x = x0; x < x1; x++) plane[y * w + x] *= change.getFloat32(4 * ((y - y0) * bw + (x - x0)), true);
        }
      }
      state.shadow = { key, plane, meter: out.meter };
      if (composedLight().join(",") === key) {
        state.dirty = true;
        requestAnimationFrame(paint);
      }
    } while (state.shadowPending);
  } catch (err) {
    state.shadow = null;  // the preview goes on without them
    console.warn("cast shadows unavailable:", err);
  } finally {
    state.shadowBusy = false;
  }
}

// The light the preview shows: the server applies the exposure itself when its runtime supports it.
function previewLight(light) {
  if (!state.info.exposure || state.exposure.mode === "physical") return light;
  const ev = state.exposure.mode === "ev" ? state.exposure.ev : 0;
  const meta = state.info.preview;
  const s = sh.exposureScale(state.layers.exposure, light, meta.exposure_target, 0, 1, meta.exposure_power ?? 1);
  // float32 as the server holds the exposed light, the faces' cast shadows metered (when known for this light),
  // then the shoulder's loss given back, the highlight guard (its bound counted from the light as it came), then the
  // EV (relight_rt.light.exposure.guarded)
  const cast = shadowFor(light);
  const meter = cast ? cast.meter : 1;
  const exposed = sh.scale(sh.scale(light, s).map((v) => Math.fround(v)), meter).map((v) => Math.fround(v));
  const up = sh.shoulderGain(state.layers.highlight, exposed, meta.own_white, meta.shoulder_knee,
    meta.shoulder_max_up, meta.exposure_power ?? 1, meta.shoulder_tol, meta.shoulder_samples);
  const lifted = sh.scale(exposed, up).map((v) => Math.fround(v));
  const guard = sh.highlightFactor(state.layers.highlight, lifted, meta.highlight_limit, meta.highlight_allowed,
    meta.highlight_max_down / up);
  // an EV acts on the light as seen: 2 ** (EV / display_gamma) on the encoded values
  // (relight_rt.light.exposure.ev_gain)
  return sh.scale(light, s * meter * up * guard * Math.pow(2, ev / meta.display_gamma));
}

// The background's grade the preview draws: the final result's (sh.backgroundGrade) when the toggle asks for it.
function previewGrade(shown) {
  if (!state.info.original_background || !$("grade-background").checked) return [1, 1, 1];
  const meta = state.info.preview;
  return sh.backgroundGrade(state.layers.grade, shown, meta.display_gamma);
}

// ------------------------------------------------------------------------------------------------ drawing

function paint() {
  if (!state.dirty || !state.preview) return;
  state.dirty = false;
  const t0 = performance.now();
  const composed = composedLight();
  const cast = shadowFor(composed);
  state.preview.setShadow(cast ? cast.plane : null);
  const shown = previewLight(composed);
  state.preview.draw(shown, previewGrade(shown));
  // a frame that answers the user's input is timed: wait until it is really drawn (WebGL: the GPU), so the time
  // is true; other frames are not held up (a read-back on every frame would stall the pipeline)
  if (state.pendingInput !== null) state.preview.finish();
  const t1 = performance.now();
  state.stats.frames += 1;
  if (state.pendingInput !== null) {
    state.stats.latencies.push(performance.now() - state.pendingInput);
    state.pendingInput = null;
    const times = state.stats.frameTimes;
    times.push(t1 - t0);
    if (times.length > 30) times.shift();
    showSpeed();
  }
  drawSphere();
  state.stats.last = { preview: t1 - t0, sphere: performance.now() - t1 };
}

function lightChanged(event) {
  state.seq += 1;
  state.dirty = true;
  if (event && state.pendingInput === null) state.pendingInput = event.timeStamp;
  $("result").hidden = true;
  for (const id of ["export-png", "export-npy", "export-json"]) $(id).classList.add("disabled");
  setBadge(`live preview · diffuse · ${state.preview ? state.preview.kind : ""}`);
  requestAnimationFrame(paint);
}

function setBadge(text) {
  $("badge").textContent = text;
}

// The header: the preview's size and renderer, and (once frames have been drawn for the user's changes)
// the median time of the latest of them.
function showSpeed() {
  const p = state.info.preview;
  let text = `live preview ${p.width}×${p.height} · ${state.preview.kind}`;
  const times = [...state.stats.frameTimes].sort((a, b) => a - b);
  if (times.length) {
    const t = times[Math.floor(times.length / 2)];
    text += ` · ${t < 0.1 ? "under 0.1" : t < 10 ? t.toFixed(1) : t.toFixed(0)} ms a frame`;
  }
  $("status").textContent = text;
}

// ------------------------------------------------------------------------------------------------ view

// Before/after: the original photo over the relit one while the key (B or \) or the button is held.
function showBefore(on) {
  if (state.before === on) return;
  state.before = on;
  $("original").hidden = !on;
  $("before-label").hidden = !on;
  $("before").setAttribute("aria-pressed", String(on));
}

const BEFORE_KEYS = new Set(["b", "B", "\\"]);

function typing(target) {
  return target instanceof HTMLElement && (target.isContentEditable || target.tagName === "TEXTAREA" ||
    (target.tagName === "INPUT" && !["range", "checkbox", "color", "file", "button"].includes(target.type)));
}

function bindView() {
  const info = state.info;
  const layers = state.layers;
  const face = facePoint(layers.mask, layers.width, layers.height, info.width, info.height);
  const zoom = $("zoom-level");
  state.view = new ZoomView($("frame"), $("view"), info.width, info.height, {
    face,
    onChange: (v) => { zoom.value = `${Math.round(v.percent)} %`; },
  });
  $("zoom-fit").addEventListener("click", () => state.view.fit());
  $("zoom-100").addEventListener("click", () => state.view.actualSize());
  const original = $("original");
  original.draggable = false;
  $("result").draggable = false;
  original.src = "/api/photo.png";

  window.addEventListener("keydown", (e) => {
    if (!BEFORE_KEYS.has(e.key) || e.ctrlKey || e.metaKey || e.altKey || typing(e.target)) return;
    e.preventDefault();
    showBefore(true);
  });
  window.addEventListener("keyup", (e) => { if (BEFORE_KEYS.has(e.key)) showBefore(false); });
  window.addEventListener("blur", () => showBefore(false));
  const button = $("before");
  button.addEventListener("pointerdown", (e) => {
    if (e.button !== 0) return;
    button.setPointerCapture(e.pointerId);
    showBefore(true);
  });
  for (const type of ["pointerup", "pointercancel", "lostpointercapture"]) {
    button.addEventListener(type, () => showBefore(false));
  }
  button.addEventListener("keydown", (e) => {
    if (e.key === " " || e.key === "Enter") { e.preventDefault(); showBefore(true); }
  });
  button.addEventListener("keyup", (e) => { if (e.key === " " || e.key === "Enter") showBefore(false); });
  button.addEventListener("blur", () => showBefore(false));
}

const sphereCanvas = () => $("sphere");

function sphereGeometry() {
  const c = sphereCanvas();
  const half = c.width / 2;
  return { c, half, radius: half / RHO_MAX - 6 };
}

// Per-pixel irradiance weights LOBE_l · Y_k(n) of the ball, computed once per canvas size.
let sphereCache = null;

function sphereWeights(size, radius) {
  if (sphereCache && sphereCache.size === size) return sphereCache;
  const index = [], weights = [];
  for (let j = 0; j < size; j++) {
    for (let i = 0; i < size; i++) {
      const u = (i + 0.5 - radius) / radius, v = (radius - j - 0.5) / radius;
      const r2 = u * u + v * v;
      if (r2 > 1) continue;
      const y = sh.basis(Math.sqrt(1 - r2), u, v);
      index.push(j * size + i);
      for (let k = 0; k < 9; k++) weights.push(sh.LOBE[sh.BAND[k]] * y[k]);
    }
  }
  sphereCache = { size, index: Int32Array.from(index), weights: Float32Array.from(weights) };
  return sphereCache;
}

function drawSphere() {
  const { c, half, radius } = sphereGeometry();
  const ctx = c.getContext("2d");
  const px = c.width / 440;  // line widths and the marker are drawn for a 440-pixel canvas
  ctx.clearRect(0, 0, c.width, c.height);
  // the ring: behind the person
  ctx.beginPath();
  ctx.arc(half, half, radius * RHO_MAX, 0, 2 * Math.PI);
  ctx.arc(half, half, radius, 0, 2 * Math.PI, true);
  ctx.fillStyle = "#1c1f26";
  ctx.fill();
  ctx.fillStyle = "#6c7380";
  ctx.font = `${Math.round(c.width / 17)}px system-ui, sans-serif`;
  ctx.textAlign = "center";
  ctx.fillText("behind", half, half - radius * (1 + RHO_MAX) / 2 + 5 * px);
  // the ball, lit by the light the preview shows (irradiance of a white diffuse sphere, clipped)
  const L = previewLight(composedLight());
  const size = Math.ceil(2 * radius);
  const { index, weights } = sphereWeights(size, radius);
  const img = ctx.createImageData(size, size);
  const data = img.data;
  for (let p = 0; p < index.length; p++) {
    const o = 4 * index[p], w = 9 * p;
    for (let ch = 0; ch < 3; ch++) {
      let e = 0;
      for (let k = 0; k < 9; k++) e += weights[w + k] * L[3 * k + ch];
      data[o + ch] = 255 * e;  // the clamped array clips to [0, 255]
    }
    data[o + 3] = 255;
  }
  const x0 = Math.round(half - radius), y0 = Math.round(half - radius);
  ctx.putImageData(img, x0, y0);
  // putImageData replaced the ring's pixels in the square; redraw the ring outside the ball
  ctx.save();
  ctx.beginPath();
  ctx.rect(x0, y0, size, size);
  ctx.arc(half, half, radius, 0, 2 * Math.PI, true);
  ctx.clip();
  ctx.beginPath();
  ctx.arc(half, half, radius * RHO_MAX, 0, 2 * Math.PI);
  ctx.arc(half, half, radius, 0, 2 * Math.PI, true);
  ctx.fillStyle = "#1c1f26";
  ctx.fill();
  ctx.restore();
  ctx.beginPath();
  ctx.arc(half, half, radius, 0, 2 * Math.PI);
  ctx.strokeStyle = "#3a404c";
  ctx.lineWidth = 2 * px;
  ctx.stroke();
  // the lamp
  const [u, v] = sh.directionToWidget(state.lamp.direction, RHO_MAX);
  const x = half + u * radius, y = half - v * radius;
  const behind = state.lamp.direction[0] < 0;
  ctx.beginPath();
  ctx.arc(x, y, px * (16 + state.lamp.size / 6), 0, 2 * Math.PI);
  const [r, g, b] = state.lamp.colour.map((t) => Math.round(255 * t));
  ctx.fillStyle = state.lamp.on ? `rgb(${r},${g},${b})` : "#555";
  ctx.fill();
  ctx.lineWidth = 3 * px;
  ctx.setLineDash(behind ? [5 * px, 4 * px] : []);
  ctx.strokeStyle = "#ffb347";
  ctx.stroke();
  ctx.setLineDash([]);
}

function pointerToDirection(event) {
  const { c, half, radius } = sphereGeometry();
  const rect = c.getBoundingClientRect();
  const px = ((event.clientX - rect.left) / rect.width) * c.width;
  const py = ((event.clientY - rect.top) / rect.height) * c.height;
  return sh.widgetToDirection((px - half) / radius, (half - py) / radius, RHO_MAX);
}

// ------------------------------------------------------------------------------------------------ server

// One message box; `source` ("render", "upload") so that a success clears only its own kind of error.
function showMessage(text, source) {
  const box = $("message");
  if (!text && box.dataset.source !== source) return;
  box.textContent = text || "";
  box.dataset.source = source;
  box.hidden = !text;
}

async function api(path, options) {
  const res = await fetch(path, options);
  if (!res.ok) {
    let text = `${res.status} ${res.statusText}`;
    try { text = (await res.json()).error || text; } catch (e) { /* not JSON */ }
    throw new Error(text);
  }
  return res;
}

async function requestFull() {
  fetchShadow();  // the light has settled: the preview draws its cast shadows too
  const seq = state.seq;
  const light = composedLight();
  // a group relit person by person: the preview draws the group's layers (one body), the full result each person
  setBadge(state.info.people > 1 ? "live preview (the group lit as one) · full result on its way…"
    : "live preview · full result on its way…");
  try {
    const res = await api("/api/render", {
      method: "POST",
      headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ light, exposure: exposureValue(), grade_background: $("grade-background").checked }),
    });
    const out = await res.json();
    if (seq !== state.seq) return;  // the light moved on meanwhile
    const img = $("result");
    img.onload = () => {
      if (seq !== state.seq) return;
      img.hidden = false;
      state.result = { ...out, seq };
      const stage = state.info.diffuse_only ? "diffuse only (no stage 2 model)" : "stage 2 + full-resolution detail";
      const people = state.info.people > 1 ? ` · ${state.info.people} people, each relit on their own` : "";
      setBadge(`full result · ${state.info.width}×${state.info.height} · ${stage}${people} · ${(out.seconds * 1000).toFixed(0)} ms`);
      setExport(out);
    };
    img.src = `/api/result/${out.id}.png`;
    showMessage("", "render");
  } catch (err) {
    showMessage(`full result failed: ${err.message}`, "render");
  }
}

function setExport(out) {
  const links = { "export-png": `/api/result/${out.id}.png?download=1`,
    "export-npy": `/api/result/${out.id}/light.npy?download=1`,
    "export-json": `/api/result/${out.id}/light.json?download=1` };
  for (const [id, href] of Object.entries(links)) {
    const a = $(id);
    a.href = href;
    a.classList.remove("disabled");
  }
  $("command").textContent = out.command;
  $("copy-command").disabled = false;
}

async function uploadLight(input, path, label) {
  const file = input.files && input.files[0];
  if (!file) return;
  const limit = state.info.max_upload_mb * 1024 * 1024;
  try {
    if (file.size > limit) throw new Error(`${label}: the file is larger than ${state.info.max_upload_mb} MiB`);
    const isScene = label === "scene";
    const url = isScene ? `${path}${sceneKeyQuery()}` : path;
    const res = await api(url, { method: "POST", body: file, headers: { "Content-Type": "application/octet-stream" } });
    const { light } = await res.json();
    const name = `upload:${file.name}`;
    if (isScene) {  // the key-light handle re-reads this photo's light with the key the user sets
      state.scene = { file, name, path, seq: 0 };
      $("scene-key").hidden = false;
    }
    const select = $("base");
    let option = [...select.options].find((o) => o.value === name);
    if (!option) {
      option = new Option(`${label}: ${file.name}`, name);
      select.add(option);
    }
    state.uploads[name] = light.flat();
    select.value = name;
    setBase(name);
    showMessage("", "upload");
  } catch (err) {
    showMessage(err.message, "upload");
  } finally {
    input.value = "";
  }
}

// The scene photo's key light (the server's ?key=AZ,EL): the automatic one unless the user steers it.
function sceneKeyQuery() {
  if (!$("scene-key-on").checked) return "";
  return `?key=${Number($("scene-key-az").value)},${Number($("scene-key-el").value)}`;
}

async function sceneKeyChanged() {
  const scene = state.scene;
  if (!scene) return;
  const seq = ++scene.seq;
  try {
    const res = await api(`${scene.path}${sceneKeyQuery()}`,
      { method: "POST", body: scene.file, headers: { "Content-Type": "application/octet-stream" } });
    const { light } = await res.json();
    if (seq !== scene.seq || state.scene !== scene) return;  // the handle moved on meanwhile
    state.uploads[scene.name] = light.flat();
    if (state.base.name === scene.name) setBase(scene.name);
    showMessage("", "upload");
  } catch (err) {
    showMessage(err.message, "upload");
  }
}

function bindSceneKey() {
  const on = $("scene-key-on"), az = $("scene-key-az"), el = $("scene-key-el");
  const show = () => {
    az.parentElement.querySelector("output").textContent = `${az.value}°`;
    el.parentElement.querySelector("output").textContent = `${el.value}°`;
  };
  show();
  on.addEventListener("change", () => { az.disabled = el.disabled = !on.checked; sceneKeyChanged(); });
  for (const input of [az, el]) {
    input.addEventListener("input", show);
    input.addEventListener("change", () => sceneKeyChanged());  // on release: one request per setting
  }
}

// ------------------------------------------------------------------------------------------------ panorama

// A panorama the server was started with, seen in the view the sliders set: its plate, and its light turned to
// that view as the base light (the lamp and the ambient off: the person lit by the panorama alone).
async function panoramaChanged() {
  const seq = (state.panoramaSeq = (state.panoramaSeq || 0) + 1);
  const view = ["pano-az", "pano-el", "pano-fov"].map((id) => Number($(id).value));
  try {
    const res = await api("/api/panorama-view", {
      method: "POST",
      headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ panorama: Number($("panorama").value), view }),
    });
    const out = await res.json();
    if (seq !== state.panoramaSeq) return;  // the sliders moved on meanwhile
    const plate = $("panorama-plate");
    plate.src = `/api/panorama/${out.id}.png`;
    plate.hidden = false;
    state.panorama = out;
    const name = "panorama";
    const select = $("base");
    let option = [...select.options].find((o) => o.value === name);
    if (!option) {
      option = new Option("", name);
      select.add(option);
    }
    option.textContent = `panorama: ${out.name} ${out.view.map((v) => Math.round(v)).join(",")}`;
    state.uploads[name] = out.light.flat();
    state.lamp.on = false;
    $("lamp-on").checked = false;
    state.ambient = 0;
    setSlider("ambient", 0);
    state.base.rotate = 0;
    setSlider("base-rotate", 0);
    state.base.level = 1;
    setSlider("base-level", 1);
    select.value = name;
    setBase(name);
    showMessage("", "panorama");
  } catch (err) {
    showMessage(err.message, "panorama");
  }
}

function setSlider(id, value) {
  const input = $(id);
  input.value = String(value);
  input.dispatchEvent(new Event("show"));
}

function bindPanorama() {
  const names = state.info.panoramas || [];
  if (!names.length) return;
  $("panorama-box").hidden = false;
  const select = $("panorama");
  names.forEach((n, i) => select.add(new Option(n, String(i))));
  select.addEventListener("change", () => panoramaChanged());
  for (const [id, unit] of [["pano-az", "°"], ["pano-el", "°"], ["pano-fov", "°"]]) {
    const input = $(id);
    const show = () => { input.parentElement.querySelector("output").textContent = `${input.value}${unit}`; };
    show();
    input.addEventListener("input", show);
    input.addEventListener("change", () => panoramaChanged());  // on release: one request per view
  }
  $("pano-use").addEventListener("click", () => panoramaChanged());
}

// ------------------------------------------------------------------------------------------------ panel

function setBase(name) {
  const info = state.info;
  state.base.name = name;
  if (name === "none") state.base.light = sh.zeros();
  else if (name === "own") state.base.light = info.own_light.flat();
  else if (name.startsWith("preset:")) state.base.light = info.presets[name.slice(7)].flat();
  else state.base.light = state.uploads[name];
  presetExposure(name.startsWith("preset:") ? (info.preset_exposure || {})[name.slice(7)] || 0 : 0);
  lightChanged();
  requestFull();
}

// A preset that asks for its own exposure (night: a stop darker; relight_rt.lights.preset_exposure) sets the
// exposure controls to it, where they show; leaving it for another light gives "auto" back, unless the user has
// changed the exposure since.
function presetExposure(ev) {
  const e = state.exposure;
  if (!state.info.exposure || e.mode === "physical" || (!ev && !e.byPreset)) return;
  if (e.byPreset && (e.mode !== "ev" || e.ev !== e.byPreset)) { e.byPreset = 0; if (!ev) return; }
  e.mode = ev ? "ev" : "auto";
  e.ev = ev;
  e.byPreset = ev;
  $("exposure-mode").value = e.mode;
  const slider = $("exposure-ev");
  slider.value = String(ev);
  slider.parentElement.querySelector("output").textContent = `${ev > 0 ? "+" : ""}${ev.toFixed(1)}`;
}

function bindSlider(id, apply, format) {
  const input = $(id);
  const out = input.parentElement.querySelector("output");
  const show = () => { if (out) out.textContent = format(Number(input.value)); };
  show();
  input.addEventListener("show", show);  // set from the script (setSlider)
  input.addEventListener("input", (e) => { apply(Number(input.value)); show(); lightChanged(e); });
  input.addEventListener("change", () => requestFull());
}

function bindPanel() {
  const info = state.info;
  const select = $("base");
  for (const name of Object.keys(info.presets)) select.add(new Option(`preset: ${name}`, `preset:${name}`));
  select.addEventListener("change", () => setBase(select.value));
  state.uploads = {};

  bindSlider("lamp-intensity", (v) => { state.lamp.intensity = v; }, (v) => v.toFixed(2));
  bindSlider("lamp-size", (v) => { state.lamp.size = v; }, (v) => `${v}°`);
  bindSlider("ambient", (v) => { state.ambient = v; }, (v) => v.toFixed(2));
  bindSlider("base-rotate", (v) => { state.base.rotate = v; }, (v) => `${v}°`);
  bindSlider("base-level", (v) => { state.base.level = v; }, (v) => v.toFixed(2));
  bindSlider("exposure-ev", (v) => { state.exposure.ev = v; }, (v) => `${v > 0 ? "+" : ""}${v.toFixed(1)}`);
  $("lamp-on").addEventListener("change", (e) => { state.lamp.on = e.target.checked; lightChanged(e); requestFull(); });
  const colour = $("lamp-colour");
  colour.addEventListener("input", (e) => { state.lamp.colour = hexToRgb(colour.value); lightChanged(e); });
  colour.addEventListener("change", () => requestFull());
  $("grade-background").addEventListener("change", (e) => { lightChanged(e); requestFull(); });
  $("grade-background-box").hidden = !info.original_background;
  const mode = $("exposure-mode");
  mode.addEventListener("change", (e) => { state.exposure.mode = mode.value; lightChanged(e); requestFull(); });
  if (!info.exposure) {  // this runtime's Relighter.relight keeps the light as set
    mode.value = "physical";
    state.exposure.mode = "physical";
    mode.disabled = true;
    $("exposure-ev").disabled = true;
    const note = $("exposure-note");
    note.textContent = "This runtime has no exposure control yet: the light is used as set (physical).";
    note.hidden = false;
  }
  $("envmap-file").addEventListener("change", (e) => uploadLight(e.target, "/api/envmap", "environment map"));
  $("photo-file").addEventListener("change", (e) => uploadLight(e.target, "/api/photo-light", "photo"));
  $("background-file").addEventListener("change", (e) => uploadLight(e.target, "/api/background-light", "scene"));
  bindSceneKey();
  bindPanorama();
  $("copy-command").addEventListener("click", () => navigator.clipboard && navigator.clipboard.writeText($("command").textContent));

  const sphere = sphereCanvas();
  const side = Math.round(184 * Math.min(2, Math.max(1, window.devicePixelRatio || 1)));  // sharp, not wasteful
  sphere.width = side;
  sphere.height = side;
  let dragging = false;
  sphere.addEventListener("pointerdown", (e) => {
    dragging = true;
    sphere.setPointerCapture(e.pointerId);
    state.lamp.direction = pointerToDirection(e);
    lightChanged(e);
  });
  sphere.addEventListener("pointermove", (e) => {
    if (!dragging) return;
    state.lamp.direction = pointerToDirection(e);
    lightChanged(e);
  });
  const release = () => {
    if (!dragging) return;
    dragging = false;
    requestFull();
  };
  sphere.addEventListener("pointerup", release);
  sphere.addEventListener("pointercancel", release);
  // keyboard: arrows turn the lamp about the vertical axis (left/right) or raise and lower it (up/down)
  sphere.addEventListener("keydown", (e) => {
    const step = (5 * Math.PI) / 180;
    const [x, y, z] = state.lamp.direction;
    let azimuth = Math.atan2(y, x), elevation = Math.asin(Math.max(-1, Math.min(1, z / Math.hypot(x, y, z))));
    if (e.key === "ArrowLeft") azimuth -= step;
    else if (e.key === "ArrowRight") azimuth += step;
    else if (e.key === "ArrowUp") elevation = Math.min(Math.PI / 2, elevation + step);
    else if (e.key === "ArrowDown") elevation = Math.max(-Math.PI / 2, elevation - step);
    else return;
    e.preventDefault();
    const h = Math.cos(elevation);
    state.lamp.direction = [h * Math.cos(azimuth), h * Math.sin(azimuth), Math.sin(elevation)];
    lightChanged(e);
  });
  sphere.addEventListener("keyup", (e) => { if (e.key.startsWith("Arrow")) requestFull(); });
}

// ------------------------------------------------------------------------------------------------ start

async function start() {
  try {
    state.info = await (await api("/api/info")).json();
    const info = state.info;
    $("photo-name").textContent = `${info.photo} · ${info.width}×${info.height}`;
    const buffer = await (await api("/api/layers")).arrayBuffer();
    state.layers = decodeLayers(buffer, info.preview);
    const renderer = new URLSearchParams(location.search).get("renderer") || "auto";
    state.preview = createPreview($("preview"), state.layers,
      { checker: info.background === "transparent", renderer, light: composedLight() });
    bindPanel();
    bindView();
    const timings = state.preview.timings;  // the trial frames that chose the renderer
    if (timings) {
      $("status").title = "renderer chosen by timing: " +
        Object.entries(timings).map(([k, t]) => `${k} ${t.toFixed(1)} ms`).join(", ");
    }
    showSpeed();
    lightChanged();
    paint();
    document.body.dataset.ready = "1";
    await requestFull();
  } catch (err) {
    $("status").textContent = "failed to start";
    showMessage(err.message, "start");
  }
}

// for tests and benchmarks
window.studio = { sh, state, composedLight, previewLight, previewGrade, paint, requestFull, decodeLayers, createPreview,
  facePoint, panoramaChanged, fetchShadow };
start();
