// The live preview: diffuse = clip(albedo ⊙ max(0, T·L) ⊙ k, 0, 1) per pixel, composited over the
// background (albedo and the result are premultiplied by the mask): out = bg · g · (1 − mask) + diffuse, g the
// background's grade per channel (1 unless it follows the light: sh.backgroundGrade).
// k is the final result's shaded-skin gain (relight_rt.relight.look.shaded_skin): where the skin weight w says
// skin and the light darkens it by r = Y(max(0, T·L)) / (T·W) (W the photo's own light, white), each channel
// takes 1 + w · (clamp(1 + (r^(g − 1) − 1) · c, 1/4, 4) − 1), c the skin's chroma (P − Y) / P; elsewhere 1.
// On the kept background's rim (the automatic matte's outline over the photo's own background:
// relight_rt.relight.kept_rim) the straight colour takes rim · (1 − g) in linear light where g, its luminance over
// the own colour's, is below 1, as the final result does (rimPixels; drawn again over its pixels alone).
// WebGL 2 (a fragment shader, float textures) where available, otherwise Canvas 2D in JavaScript.

// Decode the server's layer binary (relight_rt.apps.studio.core Studio.layers_bytes) into float planes; the Python
// mirror is relight_rt.apps.studio.preview.unpack_layers.
export function decodeLayers(buffer, meta) {
  const n = meta.width * meta.height;
  const q16 = new Uint16Array(buffer, 0, 9 * n);
  const q8 = new Uint8Array(buffer, 18 * n, 11 * n);
  const transport = [];
  for (let k = 0; k < 9; k++) {
    const plane = new Float32Array(n);
    const lo = meta.transport_offset[k], s = meta.transport_scale[k];
    for (let p = 0; p < n; p++) plane[p] = lo + q16[k * n + p] * s;
    transport.push(plane);
  }
  const eight = (i) => {
    const plane = new Float32Array(n);
    for (let p = 0; p < n; p++) plane[p] = q8[i * n + p] / 255;
    return plane;
  };
  // the exposure sample: float32 planes (transport 0..8, albedo r, g, b, mask) of the person's network pixels
  const ns = meta.exposure_samples;
  const f = new Float32Array(buffer, meta.exposure_offset, 13 * ns);
  const plane = (i) => f.subarray(i * ns, (i + 1) * ns);
  // the highlight guard's sample: float32 planes (lit r, g, b, steady r, g, b, transport 0..8)
  const nh = meta.highlight_samples;
  const g = new Float32Array(buffer, meta.highlight_offset, 15 * nh);
  const guard = (i) => g.subarray(i * nh, (i + 1) * nh);
  // the background grade's sample: float32 planes (lit r, g, b, steady r, g, b, transport 0..8, weight, knee,
  // own r, g, b, the near-neutral darks' weight)
  const ng = meta.grade_samples;
  const gr = new Float32Array(buffer, meta.grade_offset, 21 * ng);
  const graded = (i) => gr.subarray(i * ng, (i + 1) * ng);
  // the head pass's blend on some of those pixels: their indices (int32), then float32 planes (weight, skin, body
  // scale, body stays, scale, stays, transport 0..8)
  const nb = meta.grade_head_samples;
  const hb = new Float32Array(buffer, meta.grade_head_offset + 4 * nb, 15 * nb);
  const blended = (i) => hb.subarray(i * nb, (i + 1) * nb);
  // the kept background's rim: its preview pixels (int32), then float32 planes (linear r, g, b)
  const nr = meta.rim_samples ?? 0;
  const rimOffset = meta.rim_offset ?? meta.grade_head_offset + 64 * nb;
  const rf = new Float32Array(buffer, rimOffset + 4 * nr, 3 * nr);
  return {
    width: meta.width,
    height: meta.height,
    transport,
    albedo: [eight(0), eight(1), eight(2)],
    mask: eight(3),
    background: [eight(4), eight(5), eight(6)],
    skinChroma: [7, 8, 9].map((i) => eight(i).map((v) => 2 * v - 1)),
    skin: eight(10),
    skinExponent: meta.skin_chroma,
    ownWhite: meta.own_white,
    exposure: {
      transport: [0, 1, 2, 3, 4, 5, 6, 7, 8].map(plane),
      albedo: [plane(9), plane(10), plane(11)],
      mask: plane(12),
    },
    highlight: {
      lit: [guard(0), guard(1), guard(2)],
      steady: [guard(3), guard(4), guard(5)],
      transport: [6, 7, 8, 9, 10, 11, 12, 13, 14].map(guard),
    },
    grade: {
      lit: [graded(0), graded(1), graded(2)],
      steady: [graded(3), graded(4), graded(5)],
      transport: [6, 7, 8, 9, 10, 11, 12, 13, 14].map(graded),
      weight: graded(15),
      knee: graded(16),
      own: [graded(17), graded(18), graded(19)],
      neutral: graded(20),
      head: {
        index: new Int32Array(buffer, meta.grade_head_offset, nb),
        weight: blended(0),
        skin: blended(1),
        bodyScale: blended(2),
        bodyStays: blended(3),
        scale: blended(4),
        stays: blended(5),
        transport: [6, 7, 8, 9, 10, 11, 12, 13, 14].map(blended),
      },
      neutralLift: meta.neutral_lift,
      neutralChromaExp: meta.neutral_chroma_exp,
    },
    rim: {
      index: new Int32Array(buffer, rimOffset, nr),
      rim: [0, 1, 2].map((i) => rf.subarray(i * nr, (i + 1) * nr)),
    },
  };
}

// sRGB (one channel, in [0, 1]) to linear light and back (relight_rt.image.color).
const decode = (v) => (v <= 0.04045 ? v / 12.92 : Math.pow((v + 0.055) / 1.055, 2.4));
const RIM_LEAST = 0.5 / 255 / 12.92;  // a rim pixel whose own luminance is below this takes none (kept_rim.LEAST)
const LEVELS = 4096;  // the Canvas renderer's tables (the render's: relight_rt.relight.kept_rim)
const DECODE = Float32Array.from({ length: LEVELS }, (_, i) => decode(i / (LEVELS - 1)));
const ENCODE = Float32Array.from({ length: LEVELS }, (_, i) => {
  const x = (i / (LEVELS - 1)) ** 2;  // indexed by sqrt(linear)
  return x <= 0.0031308 ? 12.92 * x : 1.055 * Math.pow(x, 1 / 2.4) - 0.055;
});

// The kept background's rim as the page draws it (the Python mirror: preview.with_rim): per rim pixel its flat
// index, and rim r, g, b (linear), the own colour's linear luminance (the straight albedo under the photo's own light,
// white, clipped as drawn; 0: the pixel takes none), the mask.
export function rimPixels(layers) {
  const { index, rim } = layers.rim;
  const { transport: T, albedo: A, mask: M, ownWhite: W } = layers;
  const data = new Float32Array(5 * index.length);
  for (let j = 0, u = 0; j < index.length; j++, u += 5) {
    const p = index[j], m = M[p];
    let own = 0;
    for (let k = 0; k < 9; k++) own += T[k][p] * W[k];
    own = Math.max(own, 0);
    const y = m > 0 ? 0.2126 * decode(Math.min(1, Math.min(1, A[0][p] * own) / m))
      + 0.7152 * decode(Math.min(1, Math.min(1, A[1][p] * own) / m))
      + 0.0722 * decode(Math.min(1, Math.min(1, A[2][p] * own) / m)) : 0;
    data[u] = rim[0][j]; data[u + 1] = rim[1][j]; data[u + 2] = rim[2][j];
    data[u + 3] = y >= RIM_LEAST ? y : 0; data[u + 4] = m;
  }
  return { index, data };
}

const VERTEX = `#version 300 es
in vec2 pos;
void main() { gl_Position = vec4(pos, 0.0, 1.0); }`;

// The kept rim's pass: one point per rim pixel (its centre in clip space), its rim and own luminance passed on.
const RIM_VERTEX = `#version 300 es
in vec2 pos;
in vec4 rim;  // linear r, g, b, the own colour's linear luminance
flat out vec4 kept;
void main() { gl_Position = vec4(pos, 0.0, 1.0); gl_PointSize = 1.0; kept = rim; }`;

// The picture; with RIM (the rim's pass, drawn over its pixels alone) the kept rim added where the light darkens
// the edge: rim (1 - g) in linear light, g the straight colour's linear luminance over the own colour's.
const fragment = (rim) => `#version 300 es
precision highp float;
precision highp sampler2D;
uniform sampler2D t0;  // T0..T3
uniform sampler2D t1;  // T4..T7
uniform sampler2D t2;  // T8, albedo r, g, b (premultiplied)
uniform sampler2D t3;  // background r, g, b, mask
uniform sampler2D t4;  // skin chroma r, g, b (in [-1, 1]), skin weight
uniform sampler2D t5;  // the faces' cast shadows x the head pass's change: the factor on the shading (1: none; setShadow)
uniform vec3 L[9];
uniform float W[9];  // the photo's own light, white (one column)
uniform float G;  // the shaded-skin exponent
uniform int height;
uniform bool checker;
uniform vec3 grade;  // the background's gain per channel
${rim ? "flat in vec4 kept;" : ""}
out vec4 colour;
void main() {
  ivec2 p = ivec2(int(gl_FragCoord.x), height - 1 - int(gl_FragCoord.y));
  vec4 a = texelFetch(t0, p, 0), b = texelFetch(t1, p, 0), c = texelFetch(t2, p, 0), d = texelFetch(t3, p, 0);
  vec3 s = a.x * L[0] + a.y * L[1] + a.z * L[2] + a.w * L[3]
         + b.x * L[4] + b.y * L[5] + b.z * L[6] + b.w * L[7] + c.x * L[8];
  vec4 e = texelFetch(t4, p, 0);
  vec3 lit = max(s, 0.0) * texelFetch(t5, p, 0).r;
  float own = a.x * W[0] + a.y * W[1] + a.z * W[2] + a.w * W[3] + b.x * W[4] + b.y * W[5] + b.z * W[6]
            + b.w * W[7] + c.x * W[8];
  float r = dot(lit, vec3(0.2126, 0.7152, 0.0722)) / max(own, 1e-3);
  float boost = pow(clamp(r, 1e-4, 1.0), G - 1.0) - 1.0;
  vec3 gain = 1.0 + e.a * (clamp(1.0 + boost * e.rgb, 0.25, 4.0) - 1.0);
  vec3 diffuse = clamp(c.yzw * lit * gain, 0.0, 1.0);
${rim ? `  vec3 v = min(diffuse / d.a, 1.0);
  vec3 lin = mix(v / 12.92, pow((v + 0.055) / 1.055, vec3(2.4)), step(0.04045, v));
  float g = dot(lin, vec3(0.2126, 0.7152, 0.0722)) / kept.a;
  if (g >= 1.0) discard;  // the light does not darken it: the first pass's pixel stays
  vec3 x = clamp(lin + kept.rgb * (1.0 - g), 0.0, 1.0);
  diffuse = mix(12.92 * x, 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, x)) * d.a;` : ""}
  vec3 bg = min(d.rgb * grade, 1.0);
  if (checker) {
    bool odd = ((p.x / 12) + (p.y / 12)) % 2 == 1;
    bg = vec3(odd ? 0.78 : 0.9);
  }
  colour = vec4(bg * (1.0 - d.a) + diffuse, 1.0);
}`;

function compile(gl, type, source) {
  const shader = gl.createShader(type);
  gl.shaderSource(shader, source);
  gl.compileShader(shader);
  if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
  return shader;
}

class WebGLPreview {
  constructor(canvas, layers, checker) {
    const gl = canvas.getContext("webgl2", { preserveDrawingBuffer: false, antialias: false });
    if (!gl) throw new Error("no WebGL 2");
    this.kind = "WebGL 2";
    this.canvas = canvas;
    this.gl = gl;
    this.layers = layers;
    const link = (vertex, frag) => {
      const prog = gl.createProgram();
      gl.attachShader(prog, compile(gl, gl.VERTEX_SHADER, vertex));
      gl.attachShader(prog, compile(gl, gl.FRAGMENT_SHADER, frag));
      gl.linkProgram(prog);
      if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
      return prog;
    };
    const prog = link(VERTEX, fragment(false));
    this.prog = prog;
    this.picture = gl.createVertexArray();
    gl.bindVertexArray(this.picture);
    const buf = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
    const loc = gl.getAttribLocation(prog, "pos");
    gl.enableVertexAttribArray(loc);
    gl.vertexAttribPointer(loc, 2, gl.FLOAT, false, 0, 0);
    const { width: w, height: h, transport: T, albedo: A, mask: M, background: B, skinChroma: C, skin: S } = layers;
    const n = w * h;
    const pack = (planes) => {
      const out = new Float32Array(4 * n);
      for (let i = 0; i < 4; i++) {
        const src = planes[i];
        for (let p = 0; p < n; p++) out[4 * p + i] = src[p];
      }
      return out;
    };
    const floatTexture = (unit, data) => {
      const tex = gl.createTexture();
      gl.activeTexture(gl.TEXTURE0 + unit);
      gl.bindTexture(gl.TEXTURE_2D, tex);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, w, h, 0, gl.RGBA, gl.FLOAT, data);
    };
    floatTexture(0, pack([T[0], T[1], T[2], T[3]]));
    floatTexture(1, pack([T[4], T[5], T[6], T[7]]));
    floatTexture(2, pack([T[8], A[0], A[1], A[2]]));
    floatTexture(3, pack([B[0], B[1], B[2], M]));
    floatTexture(4, pack([C[0], C[1], C[2], S]));
    // the cast shadows' factor, one channel (setShadow replaces it)
    gl.activeTexture(gl.TEXTURE0 + 5);
    this.shadowTexture = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, this.shadowTexture);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.R32F, w, h, 0, gl.RED, gl.FLOAT, new Float32Array(n).fill(1));
    this.shadow = null;
    // the kept rim: a second pass over its pixels alone (points), so that the picture's pass costs what it did
    const rim = rimPixels(layers), points = new Float32Array(6 * rim.index.length);
    let np = 0;
    for (let j = 0, u = 0; j < rim.index.length; j++, u += 5) {
      if (rim.data[u + 3] === 0) continue;  // its own colour too dark: no rim
      const p = rim.index[j], x = p % w, y = (p / w) | 0;
      points.set([(2 * x + 1) / w - 1, 1 - (2 * y + 1) / h], 6 * np);
      points.set(rim.data.subarray(u, u + 4), 6 * np + 2);
      np++;
    }
    this.rimPoints = np;
    this.programs = [prog];
    if (np) {
      const rimProg = link(RIM_VERTEX, fragment(true));
      this.rimVertices = gl.createVertexArray();
      gl.bindVertexArray(this.rimVertices);
      gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
      gl.bufferData(gl.ARRAY_BUFFER, points.subarray(0, 6 * np), gl.STATIC_DRAW);
      const at = gl.getAttribLocation(rimProg, "pos"), kept = gl.getAttribLocation(rimProg, "rim");
      gl.enableVertexAttribArray(at);
      gl.vertexAttribPointer(at, 2, gl.FLOAT, false, 24, 0);
      gl.enableVertexAttribArray(kept);
      gl.vertexAttribPointer(kept, 4, gl.FLOAT, false, 24, 8);
      this.programs.push(rimProg);
    }
    this.lightLocs = [];
    this.gradeLocs = [];
    for (const one of this.programs) {
      gl.useProgram(one);
      for (let i = 0; i < 6; i++) gl.uniform1i(gl.getUniformLocation(one, `t${i}`), i);
      gl.uniform1fv(gl.getUniformLocation(one, "W"), new Float32Array(layers.ownWhite));
      gl.uniform1f(gl.getUniformLocation(one, "G"), layers.skinExponent);
      gl.uniform1i(gl.getUniformLocation(one, "height"), h);
      gl.uniform1i(gl.getUniformLocation(one, "checker"), checker ? 1 : 0);
      this.lightLocs.push(gl.getUniformLocation(one, "L"));
      this.gradeLocs.push(gl.getUniformLocation(one, "grade"));
    }
    gl.viewport(0, 0, w, h);
  }

  // The faces' cast shadows to draw with: a plane (height x width Float32Array, the factor on the shading) or null.
  setShadow(plane) {
    if (plane === this.shadow) return;
    const gl = this.gl, { width: w, height: h } = this.layers;
    gl.activeTexture(gl.TEXTURE0 + 5);
    gl.bindTexture(gl.TEXTURE_2D, this.shadowTexture);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, w, h, gl.RED, gl.FLOAT, plane ?? new Float32Array(w * h).fill(1));
    this.shadow = plane;
  }

  draw(light, grade = [1, 1, 1]) {
    const gl = this.gl, L = new Float32Array(light), g = new Float32Array(grade);
    for (let i = 0; i < this.programs.length; i++) {  // the picture, then the kept rim's pixels over it
      gl.useProgram(this.programs[i]);
      gl.uniform3fv(this.lightLocs[i], L);
      gl.uniform3fv(this.gradeLocs[i], g);
      gl.bindVertexArray(i ? this.rimVertices : this.picture);
      if (i) gl.drawArrays(gl.POINTS, 0, this.rimPoints);
      else gl.drawArrays(gl.TRIANGLES, 0, 3);
    }
  }

  finish() {  // wait until the frame is really drawn (benchmarks)
    const px = new Uint8Array(4);
    this.gl.readPixels(0, 0, 1, 1, this.gl.RGBA, this.gl.UNSIGNED_BYTE, px);
  }
}

class CanvasPreview {
  constructor(canvas, layers, checker) {
    this.kind = "Canvas 2D";
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.layers = layers;
    this.image = this.ctx.createImageData(layers.width, layers.height);
    this.pixels = new Uint32Array(this.image.data.buffer);  // one store per pixel (little-endian RGBA)
    const n = layers.width * layers.height;
    const { transport: T, albedo: A, mask: M, background: B, skinChroma: C, skin: S, ownWhite: W } = layers;
    // per pixel, contiguous: T0..T8, albedo r, g, b, the background in 0..255, and 1 − mask
    const packed = new Float32Array(16 * n);
    for (let p = 0, o = 0; p < n; p++, o += 16) {
      for (let k = 0; k < 9; k++) packed[o + k] = T[k][p];
      packed[o + 9] = A[0][p]; packed[o + 10] = A[1][p]; packed[o + 11] = A[2][p];
      let r = B[0][p], g = B[1][p], b = B[2][p];
      if (checker) {
        const x = p % layers.width, y = (p / layers.width) | 0;
        r = g = b = ((((x / 12) | 0) + ((y / 12) | 0)) % 2 === 1) ? 0.78 : 0.9;
      }
      packed[o + 12] = 255 * r; packed[o + 13] = 255 * g; packed[o + 14] = 255 * b; packed[o + 15] = 1 - M[p];
    }
    this.packed = packed;
    // the skin's pixels alone (a small part of the picture), drawn again with the shaded-skin gain: their index,
    // then chroma r, g, b, weight and the shading under the photo's own light (white)
    const index = [];
    for (let p = 0; p < n; p++) if (S[p] > 0) index.push(p);
    this.skinIndex = Int32Array.from(index);
    const skin = new Float32Array(5 * index.length);
    for (let j = 0, u = 0; j < index.length; j++, u += 5) {
      const p = index[j];
      let own = 0;
      for (let k = 0; k < 9; k++) own += T[k][p] * W[k];
      skin[u] = C[0][p]; skin[u + 1] = C[1][p]; skin[u + 2] = C[2][p]; skin[u + 3] = S[p]; skin[u + 4] = own;
    }
    this.skin = skin;
    // the kept rim's pixels that can take it (own colour not too dark), contiguous: their index, then per pixel
    // T0..T8, the straight albedo r, g, b, rim r, g, b, own luminance, mask, skin weight, chroma r, g, b, and the
    // shading under the photo's own light (white)
    const rim = rimPixels(layers), at = [], rimData = [];
    for (let j = 0, u = 0; j < rim.index.length; j++, u += 5) {
      const p = rim.index[j], m = rim.data[u + 4];
      if (rim.data[u + 3] === 0) continue;
      let own = 0;
      for (let k = 0; k < 9; k++) own += T[k][p] * W[k];
      at.push(p);
      rimData.push(T[0][p], T[1][p], T[2][p], T[3][p], T[4][p], T[5][p], T[6][p], T[7][p], T[8][p],
        A[0][p] / m, A[1][p] / m, A[2][p] / m, rim.data[u], rim.data[u + 1], rim.data[u + 2], rim.data[u + 3], m,
        S[p], C[0][p], C[1][p], C[2][p], own);
    }
    this.rimIndex = Int32Array.from(at);
    this.rimData = Float32Array.from(rimData);
    this.exponent = layers.skinExponent;
    this.shadow = null;
  }

  // The faces' cast shadows to draw with: a plane (height x width Float32Array, the factor on the shading) or null.
  setShadow(plane) {
    this.shadow = plane;
  }

  draw(light, grade = [1, 1, 1]) {
    const L = light;
    const gr = grade[0], gg = grade[1], gb = grade[2];
    const l0 = L[0], l1 = L[1], l2 = L[2], l3 = L[3], l4 = L[4], l5 = L[5], l6 = L[6], l7 = L[7], l8 = L[8];
    const l9 = L[9], l10 = L[10], l11 = L[11], l12 = L[12], l13 = L[13], l14 = L[14], l15 = L[15], l16 = L[16];
    const l17 = L[17], l18 = L[18], l19 = L[19], l20 = L[20], l21 = L[21], l22 = L[22], l23 = L[23], l24 = L[24];
    const l25 = L[25], l26 = L[26];
    const f = this.packed, px = this.pixels, cast = this.shadow;
    const n = px.length;
    const back = this.back = this.back ?? new Float32Array(3 * n);  // the graded background's share, + 0.5 (rounding)
    for (let p = 0, o = 0, u = 0; p < n; p++, o += 16, u += 3) {
      const k = f[o + 15];
      back[u] = Math.min(255, f[o + 12] * gr) * k + 0.5;
      back[u + 1] = Math.min(255, f[o + 13] * gg) * k + 0.5;
      back[u + 2] = Math.min(255, f[o + 14] * gb) * k + 0.5;
      const q0 = f[o], q1 = f[o + 1], q2 = f[o + 2], q3 = f[o + 3], q4 = f[o + 4], q5 = f[o + 5], q6 = f[o + 6];
      const q7 = f[o + 7], q8 = f[o + 8];
      const sr = q0 * l0 + q1 * l3 + q2 * l6 + q3 * l9 + q4 * l12 + q5 * l15 + q6 * l18 + q7 * l21 + q8 * l24;
      const sg = q0 * l1 + q1 * l4 + q2 * l7 + q3 * l10 + q4 * l13 + q5 * l16 + q6 * l19 + q7 * l22 + q8 * l25;
      const sb = q0 * l2 + q1 * l5 + q2 * l8 + q3 * l11 + q4 * l14 + q5 * l17 + q6 * l20 + q7 * l23 + q8 * l26;
      const c = cast ? cast[p] : 1;
      const dr = sr > 0 ? Math.min(1, f[o + 9] * sr * c) : 0;
      const dg = sg > 0 ? Math.min(1, f[o + 10] * sg * c) : 0;
      const db = sb > 0 ? Math.min(1, f[o + 11] * sb * c) : 0;
      const r = Math.min(255, back[u] + 255 * dr) | 0;
      const g = Math.min(255, back[u + 1] + 255 * dg) | 0;
      const b = Math.min(255, back[u + 2] + 255 * db) | 0;
      px[p] = 0xff000000 | (b << 16) | (g << 8) | r;
    }
    // the skin the light darkens: the shaded-skin gain (see the top of this file)
    const idx = this.skinIndex, s = this.skin, g1 = this.exponent - 1;
    for (let j = 0, u = 0; j < idx.length; j++, u += 5) {
      const p = idx[j], o = 16 * p, v = 3 * p;
      const q0 = f[o], q1 = f[o + 1], q2 = f[o + 2], q3 = f[o + 3], q4 = f[o + 4], q5 = f[o + 5], q6 = f[o + 6];
      const q7 = f[o + 7], q8 = f[o + 8];
      let sr = q0 * l0 + q1 * l3 + q2 * l6 + q3 * l9 + q4 * l12 + q5 * l15 + q6 * l18 + q7 * l21 + q8 * l24;
      let sg = q0 * l1 + q1 * l4 + q2 * l7 + q3 * l10 + q4 * l13 + q5 * l16 + q6 * l19 + q7 * l22 + q8 * l25;
      let sb = q0 * l2 + q1 * l5 + q2 * l8 + q3 * l11 + q4 * l14 + q5 * l17 + q6 * l20 + q7 * l23 + q8 * l26;
      const c = cast ? cast[p] : 1;
      sr = sr > 0 ? sr * c : 0; sg = sg > 0 ? sg * c : 0; sb = sb > 0 ? sb * c : 0;
      const ratio = (0.2126 * sr + 0.7152 * sg + 0.0722 * sb) / Math.max(s[u + 4], 1e-3);
      if (ratio >= 1) continue;
      const boost = Math.pow(Math.max(ratio, 1e-4), g1) - 1, w = s[u + 3];
      const kr = 1 + w * (Math.min(4, Math.max(0.25, 1 + boost * s[u])) - 1);
      const kg = 1 + w * (Math.min(4, Math.max(0.25, 1 + boost * s[u + 1])) - 1);
      const kb = 1 + w * (Math.min(4, Math.max(0.25, 1 + boost * s[u + 2])) - 1);
      const r = Math.min(255, back[v] + 255 * Math.min(1, f[o + 9] * sr * kr)) | 0;
      const g = Math.min(255, back[v + 1] + 255 * Math.min(1, f[o + 10] * sg * kg)) | 0;
      const b = Math.min(255, back[v + 2] + 255 * Math.min(1, f[o + 11] * sb * kb)) | 0;
      px[p] = 0xff000000 | (b << 16) | (g << 8) | r;
    }
    // the kept rim where the light darkens the edge: the pixel drawn again, rim (1 - g) added in linear light
    const ri = this.rimIndex, rd = this.rimData, top = LEVELS - 1;
    for (let j = 0, u = 0; j < ri.length; j++, u += 22) {
      const q0 = rd[u], q1 = rd[u + 1], q2 = rd[u + 2], q3 = rd[u + 3], q4 = rd[u + 4], q5 = rd[u + 5];
      const q6 = rd[u + 6], q7 = rd[u + 7], q8 = rd[u + 8], p = ri[j];
      let sr = q0 * l0 + q1 * l3 + q2 * l6 + q3 * l9 + q4 * l12 + q5 * l15 + q6 * l18 + q7 * l21 + q8 * l24;
      let sg = q0 * l1 + q1 * l4 + q2 * l7 + q3 * l10 + q4 * l13 + q5 * l16 + q6 * l19 + q7 * l22 + q8 * l25;
      let sb = q0 * l2 + q1 * l5 + q2 * l8 + q3 * l11 + q4 * l14 + q5 * l17 + q6 * l20 + q7 * l23 + q8 * l26;
      const c = cast ? cast[p] : 1, ow = rd[u + 21];
      sr = sr > 0 ? sr * c : 0; sg = sg > 0 ? sg * c : 0; sb = sb > 0 ? sb * c : 0;
      if (sr >= ow && sg >= ow && sb >= ow) continue;  // lit at least as the own light lights it: g >= 1
      let kr = 1, kg = 1, kb = 1;
      const w = rd[u + 17];
      if (w > 0) {  // the shaded-skin gain, as above
        const ratio = (0.2126 * sr + 0.7152 * sg + 0.0722 * sb) / Math.max(ow, 1e-3);
        if (ratio < 1) {
          const boost = Math.pow(Math.max(ratio, 1e-4), g1) - 1;
          kr = 1 + w * (Math.min(4, Math.max(0.25, 1 + boost * rd[u + 18])) - 1);
          kg = 1 + w * (Math.min(4, Math.max(0.25, 1 + boost * rd[u + 19])) - 1);
          kb = 1 + w * (Math.min(4, Math.max(0.25, 1 + boost * rd[u + 20])) - 1);
        }
      }
      const lr = DECODE[(Math.min(1, rd[u + 9] * sr * kr) * top + 0.5) | 0];
      const lg = DECODE[(Math.min(1, rd[u + 10] * sg * kg) * top + 0.5) | 0];
      const lb = DECODE[(Math.min(1, rd[u + 11] * sb * kb) * top + 0.5) | 0];
      const lost = 1 - (0.2126 * lr + 0.7152 * lg + 0.0722 * lb) / rd[u + 15];
      if (lost <= 0) continue;
      const m = 255 * rd[u + 16], v = 3 * p;
      const er = ENCODE[(Math.sqrt(Math.min(1, lr + rd[u + 12] * lost)) * top + 0.5) | 0];
      const eg = ENCODE[(Math.sqrt(Math.min(1, lg + rd[u + 13] * lost)) * top + 0.5) | 0];
      const eb = ENCODE[(Math.sqrt(Math.min(1, lb + rd[u + 14] * lost)) * top + 0.5) | 0];
      const r = Math.min(255, back[v] + m * er) | 0;
      const g = Math.min(255, back[v + 1] + m * eg) | 0;
      const b = Math.min(255, back[v + 2] + m * eb) | 0;
      px[p] = 0xff000000 | (b << 16) | (g << 8) | r;
    }
    this.ctx.putImageData(this.image, 0, 0);
  }

  finish() {}
}

function timeDraws(preview, light, n) {
  const times = [];
  for (let i = 0; i < n; i++) {
    const t0 = performance.now();
    preview.draw(light);
    preview.finish();
    times.push(performance.now() - t0);
  }
  times.sort((a, b) => a - b);
  return times[Math.floor(n / 2)];
}

// A preview on `canvas`. renderer: "webgl" (Canvas 2D only if WebGL 2 fails), "canvas", or "auto": both
// are timed on a few frames of `light` and the faster one is kept (software WebGL, as in a headless
// browser without a GPU, can be slower than the JavaScript loop; with a GPU, WebGL wins by far).
// The returned object's `canvas` is the element on the page (it may replace the one given).
export function createPreview(canvas, layers, { checker = false, renderer = "auto", light = null } = {}) {
  canvas.width = layers.width;
  canvas.height = layers.height;
  if (renderer === "canvas") return new CanvasPreview(canvas, layers, checker);
  let gl;
  try {
    gl = new WebGLPreview(canvas, layers, checker);
  } catch (err) {
    console.warn("WebGL 2 preview unavailable, using Canvas 2D:", err);
    const fresh = canvas.cloneNode(false);  // a canvas that asked for webgl2 cannot give a 2d context
    canvas.replaceWith(fresh);
    return new CanvasPreview(fresh, layers, checker);
  }
  if (renderer !== "auto" || !light) return gl;
  const spare = canvas.cloneNode(false);
  spare.width = layers.width;
  spare.height = layers.height;
  const cpu = new CanvasPreview(spare, layers, checker);
  timeDraws(gl, light, 1);  // warm up (shader compilation, texture upload)
  timeDraws(cpu, light, 1);
  const tGl = timeDraws(gl, light, 3), tCpu = timeDraws(cpu, light, 3);
  const chosen = tCpu < 0.8 * tGl ? cpu : gl;
  chosen.timings = { "WebGL 2": tGl, "Canvas 2D": tCpu };
  if (chosen === cpu) {
    const lose = gl.gl.getExtension("WEBGL_lose_context");
    if (lose) lose.loseContext();
    canvas.replaceWith(spare);
  }
  return chosen;
}
