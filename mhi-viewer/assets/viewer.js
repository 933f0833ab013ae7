// MHI viewer: written by `cargo xtask export` beside index.html and data.js.
"use strict";
// ---------------------------------------------------------------- data
const D = window.MHI_DATA;
const M = D.manifest;
const W = M.width, H = M.height, N = M.normals.length;
const hash = new URLSearchParams(location.hash.slice(1));
if (hash.has("nohud")) document.body.classList.add("nohud");
if (hash.has("novideo")) document.body.classList.add("novideo");
// The rendered video of the camera path, beside the interactive view (#novideo hides it).
if (typeof M.video === "string" && /^[\w.-]+\.mp4$/.test(M.video)) {
  const v = document.createElement("video");
  Object.assign(v, { id: "video", src: M.video, controls: true, loop: true, muted: true, autoplay: true, playsInline: true });
  v.title = "the rendered video along the camera path";
  // What the browser made of it, for a test reading the page (data-loaded="WxH" or data-error).
  v.addEventListener("loadeddata", () => { v.dataset.loaded = v.videoWidth + "x" + v.videoHeight; });
  v.addEventListener("error", () => { v.dataset.error = String(v.error && v.error.code); });
  document.body.appendChild(v);
}
const canvas = document.getElementById("c");
canvas.width = W; canvas.height = H;
// Shown at the largest whole zoom that fits the window (#zoom=k fixes it), pixels kept square.
function fit() {
  const z = +(hash.get("zoom") || Math.max(1, Math.floor(Math.min(innerWidth / W, innerHeight / H))));
  canvas.style.width = W * z + "px"; canvas.style.height = H * z + "px";
}
fit(); window.addEventListener("resize", fit);
const gl = canvas.getContext("webgl2", { preserveDrawingBuffer: true, antialias: false, alpha: false });
const hud = document.getElementById("hud");
// Text only: nothing shown here is ever parsed as HTML (the URL's #view=… reaches it).
function show(bold, rest) {
  const b = document.createElement("b"); b.textContent = bold;
  hud.replaceChildren(b, ...rest.flatMap((line, i) => i ? [document.createElement("br"), line] : [line]));
}
function fail(msg) { show(String(msg), []); document.title = "error: " + msg; throw new Error(msg); }
if (!gl) fail("this browser has no WebGL2");
// Half-float targets are renderable and blendable with EXT_color_buffer_float (32-bit ones
// would also need EXT_float_blend); 8-bit ones otherwise.
const floatTargets = !!gl.getExtension("EXT_color_buffer_float");

function bytes(b64) {
  const s = atob(b64), out = new Uint8Array(s.length);
  for (let i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
  return out;
}

// ---------------------------------------------------------------- small f64 linear algebra
// 3x3 matrices are row-major arrays of 9; poses are {R: 3x3, t: [3]} with X_cam = R X_world + t.
const mul3 = (a, b) => { const o = new Array(9).fill(0);
  for (let i = 0; i < 3; i++) for (let j = 0; j < 3; j++) for (let k = 0; k < 3; k++) o[3*i+j] += a[3*i+k] * b[3*k+j];
  return o; };
const mulv = (a, v) => [0, 1, 2].map(i => a[3*i] * v[0] + a[3*i+1] * v[1] + a[3*i+2] * v[2]);
const tr3 = a => [a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8]];
const dot = (a, b) => a[0]*b[0] + a[1]*b[1] + a[2]*b[2];
const K = c => [c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1];
const Kinv = c => [1/c.fx, 0, -c.cx/c.fx, 0, 1/c.fy, -c.cy/c.fy, 0, 0, 1];
const pose = c => ({ R: c.cam_from_world.slice(0, 9), t: c.cam_from_world.slice(9, 12) });
// ref_from_tgt = T_ref T_tgt^-1: R = R_r R_t^T, t = t_r - R t_t.
function relative(ref, tgt) {
  const R = mul3(ref.R, tr3(tgt.R));
  const Rt = mulv(R, tgt.t);
  return { R, t: [ref.t[0] - Rt[0], ref.t[1] - Rt[1], ref.t[2] - Rt[2]] };
}
function rot(yaw, pitch) {
  const cy = Math.cos(yaw), sy = Math.sin(yaw), cp = Math.cos(pitch), sp = Math.sin(pitch);
  const Ry = [cy, 0, sy, 0, 1, 0, -sy, 0, cy], Rx = [1, 0, 0, 0, cp, -sp, 0, sp, cp];
  return mul3(Rx, Ry);
}

// ---------------------------------------------------------------- textures
function tex(internal, format, type, w, h, data) {
  const t = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, t);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  gl.texImage2D(gl.TEXTURE_2D, 0, internal, w, h, 0, format, type, data);
  for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, p, gl.NEAREST);
  for (const p of [gl.TEXTURE_WRAP_S, gl.TEXTURE_WRAP_T]) gl.texParameteri(gl.TEXTURE_2D, p, gl.CLAMP_TO_EDGE);
  return t;
}
// The layers' colour: the reference's, shared (one texture), or each layer's own, tiled in one
// atlas per normal as its alphas are (a model with a colour head).
const perLayer = M.colour === "per-layer";
const colourTex = perLayer ? null : tex(gl.RGB8, gl.RGB, gl.UNSIGNED_BYTE, W, H, bytes(D.colour));
const atlasTex = M.atlases.map((a, i) => tex(gl.R8, gl.RED, gl.UNSIGNED_BYTE, a.cols * W, a.rows * H, bytes(D.alphas[i])));
const colourAtlasTex = perLayer ? M.atlases.map((a, i) => tex(gl.RGB8, gl.RGB, gl.UNSIGNED_BYTE, a.cols * W, a.rows * H, bytes(D.colours[i]))) : [];
const targets = [];
for (let i = 0; i < N; i++) {
  const t = floatTargets ? tex(gl.RGBA16F, gl.RGBA, gl.HALF_FLOAT, W, H, null) : tex(gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, W, H, null);
  const fb = gl.createFramebuffer();
  gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, t, 0);
  targets.push({ t, fb });
}
gl.bindFramebuffer(gl.FRAMEBUFFER, null);

// ---------------------------------------------------------------- shaders
function program(fs) {
  const vs = `#version 300 es
  void main() { vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
                gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0); }`;
  const p = gl.createProgram();
  for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
    const s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) fail("shader: " + gl.getShaderInfoLog(s));
    gl.attachShader(p, s);
  }
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) fail("link: " + gl.getProgramInfoLog(p));
  const u = {}; const n = gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS);
  for (let i = 0; i < n; i++) { const name = gl.getActiveUniform(p, i).name.replace("[0]", ""); u[name] = gl.getUniformLocation(p, name); }
  return { p, u };
}
// One plane of one normal, as the CPU renderer samples it: the target pixel centre through the
// plane's homography into the reference, bilinear alpha and colour with zero outside, the
// farthest plane opaque; output premultiplied for back-to-front "over".
const layerProg = program(`#version 300 es
precision highp float; precision highp int;
uniform mat3 uH; uniform ivec2 uTile; uniform ivec2 uColourTile; uniform bool uFar; uniform vec2 uSize;
uniform highp sampler2D uAlpha; uniform highp sampler2D uColour;
out vec4 o;
void main() {
  vec2 p = vec2(gl_FragCoord.x, uSize.y - gl_FragCoord.y);
  vec3 q = uH * vec3(p, 1.0);
  if (!(q.z > 1e-6)) discard;
  vec2 s = q.xy / q.z - 0.5;
  vec2 f = floor(s); vec2 fr = s - f; ivec2 i0 = ivec2(f);
  float a = 0.0; vec3 c = vec3(0.0);
  for (int k = 0; k < 4; k++) {
    ivec2 d = ivec2(k & 1, k >> 1); ivec2 ij = i0 + d;
    if (ij.x < 0 || ij.y < 0 || ij.x >= int(uSize.x) || ij.y >= int(uSize.y)) continue;
    float w = (d.x == 1 ? fr.x : 1.0 - fr.x) * (d.y == 1 ? fr.y : 1.0 - fr.y);
    a += w * texelFetch(uAlpha, uTile + ij, 0).r;
    c += w * texelFetch(uColour, uColourTile + ij, 0).rgb;
  }
  if (uFar) a = 1.0;
  o = vec4(c * a, a);
}`);
// The paper's Eq. 3 and 4: Soft weights exp(3 (2 delta - 1)) of delta = |n . ray|, normalised.
const blendProg = program(`#version 300 es
precision highp float; precision highp int;
#define N ${N}
uniform highp sampler2D uMni[N]; uniform vec3 uNormal[N]; uniform mat3 uKinv; uniform vec2 uSize;
uniform int uMode; uniform int uWhich;
out vec4 o;
void main() {
  vec2 p = vec2(gl_FragCoord.x, uSize.y - gl_FragCoord.y);
  vec3 ray = normalize(uKinv * vec3(p, 1.0));
  float w[N]; float sum = 0.0;
  for (int k = 0; k < N; k++) { float d = min(abs(dot(uNormal[k], ray)), 1.0); w[k] = exp(3.0 * (2.0 * d - 1.0)); sum += w[k]; }
  ivec2 ij = ivec2(gl_FragCoord.xy);
  vec3 c = vec3(0.0);
  vec3 m;
  // Sampler arrays take constant indices only: one block per normal.
  ${Array.from({ length: N }, (_, k) => `
  m = texelFetch(uMni[${k}], ij, 0).rgb;
  if (uMode == 0) c += w[${k}] / sum * m;
  else if (uMode == 1 && uWhich == ${k}) c = m;
  else if (uMode == 2 && uWhich == ${k}) c = vec3(w[${k}] / sum);`).join("")}
  o = vec4(clamp(c, 0.0, 1.0), 1.0);
}`);

// ---------------------------------------------------------------- rendering
const refCam = M.reference, refPose = pose(refCam);
function render(cam) {
  const tgt = pose(cam), rel = relative(refPose, tgt);
  const kr = K(refCam), ki = Kinv(cam);
  gl.viewport(0, 0, W, H);
  gl.useProgram(layerProg.p);
  if (!perLayer) { gl.activeTexture(gl.TEXTURE1); gl.bindTexture(gl.TEXTURE_2D, colourTex); }
  gl.uniform1i(layerProg.u.uColour, 1); gl.uniform1i(layerProg.u.uAlpha, 0);
  gl.uniform2f(layerProg.u.uSize, W, H);
  gl.enable(gl.BLEND); gl.blendFunc(gl.ONE, gl.ONE_MINUS_SRC_ALPHA);
  for (let i = 0; i < N; i++) {
    gl.bindFramebuffer(gl.FRAMEBUFFER, targets[i].fb);
    gl.clearColor(0, 0, 0, 0); gl.clear(gl.COLOR_BUFFER_BIT);
    gl.activeTexture(gl.TEXTURE0); gl.bindTexture(gl.TEXTURE_2D, atlasTex[i]);
    if (perLayer) { gl.activeTexture(gl.TEXTURE1); gl.bindTexture(gl.TEXTURE_2D, colourAtlasTex[i]); }
    const n = M.normals[i], nr = mulv(tr3(rel.R), n);
    const tl = Math.hypot(...rel.t);
    for (const L of M.layers.filter(l => l.normal === i)) {  // far first: back to front
      const d = L.depth * n[2], sd = d - dot(n, rel.t);
      if (!(sd > 1e-6 * Math.max(d, tl))) continue;            // plane not in front of the target
      const Mm = rel.R.slice();
      for (let r = 0; r < 3; r++) for (let c = 0; c < 3; c++) Mm[3*r+c] += rel.t[r] * nr[c] / sd;
      const Hm = mul3(mul3(kr, Mm), ki);
      gl.uniformMatrix3fv(layerProg.u.uH, false, new Float32Array(tr3(Hm)));  // GL is column-major
      gl.uniform2i(layerProg.u.uTile, L.tile_x * W, L.tile_y * H);
      if (perLayer) gl.uniform2i(layerProg.u.uColourTile, L.tile_x * W, L.tile_y * H);
      else gl.uniform2i(layerProg.u.uColourTile, 0, 0);
      gl.uniform1i(layerProg.u.uFar, L.depth_index === 0 ? 1 : 0);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
    }
  }
  gl.disable(gl.BLEND);
  gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  gl.useProgram(blendProg.p);
  for (let i = 0; i < N; i++) { gl.activeTexture(gl.TEXTURE2 + i); gl.bindTexture(gl.TEXTURE_2D, targets[i].t); }
  gl.uniform1iv(blendProg.u.uMni, Array.from({ length: N }, (_, i) => 2 + i));
  gl.uniform3fv(blendProg.u.uNormal, M.normals.flatMap(n => { const v = mulv(tr3(rel.R), n); const l = Math.hypot(...v); return v.map(x => x / l); }));
  gl.uniformMatrix3fv(blendProg.u.uKinv, false, new Float32Array(tr3(ki)));
  gl.uniform2f(blendProg.u.uSize, W, H);
  gl.uniform1i(blendProg.u.uMode, view.mode); gl.uniform1i(blendProg.u.uWhich, view.which);
  gl.drawArrays(gl.TRIANGLES, 0, 3);
}

// ---------------------------------------------------------------- camera and controls
const view = { mode: 0, which: 0, yaw: 0, pitch: 0, c: [0, 0, 0], fixed: null, playing: false };
const modes = ["blend", "multi-normal image", "blend weight"];
const baseline = M.baseline || 1.0;
function camera() {
  if (view.fixed) return view.fixed;
  const Rd = rot(view.yaw, view.pitch);            // cam_from_ref rotation
  const R = mul3(Rd, refPose.R);
  const tc = mulv(Rd, view.c);                      // t = Rd (t_ref - c) in the reference frame
  const t = mulv(Rd, refPose.t).map((x, k) => x - tc[k]);
  return { fx: refCam.fx, fy: refCam.fy, cx: refCam.cx, cy: refCam.cy, cam_from_world: [...R, ...t] };
}
function draw() {
  render(camera());
  const m = view.mode === 0 ? "blend" : modes[view.mode] + " " + view.which;
  show(m, [` · ${M.source} · N=${N}, ${M.layers.length} layers kept of ${N * M.depths.length}`,
    `drag: turn · arrows/W-S: move · wheel: forward/back · B: blend · 1-${N}: multi-normal image · ` +
    `Shift+1-${N}: its weight · P: replay the input cameras · R: reset`]);
}
let drag = null;
canvas.addEventListener("mousedown", e => { drag = [e.clientX, e.clientY]; view.fixed = null; });
window.addEventListener("mouseup", () => { drag = null; });
window.addEventListener("mousemove", e => {
  if (!drag) return;
  view.yaw += (e.clientX - drag[0]) * 0.004; view.pitch -= (e.clientY - drag[1]) * 0.004;
  drag = [e.clientX, e.clientY]; draw();
});
canvas.addEventListener("wheel", e => { e.preventDefault(); view.fixed = null; view.c[2] -= Math.sign(e.deltaY) * 0.1 * baseline; draw(); });
window.addEventListener("keydown", e => {
  const s = 0.1 * baseline, k = e.key;
  const moves = { ArrowLeft: [0, -s], ArrowRight: [0, s], ArrowUp: [1, -s], ArrowDown: [1, s], w: [2, s], s: [2, -s] };
  if (k in moves) { view.fixed = null; view.c[moves[k][0]] += moves[k][1]; }
  else if (k === "b" || k === "B") view.mode = 0;
  else if (/^[1-9]$/.test(k) && +k <= N) { view.mode = 1; view.which = +k - 1; }
  else if (e.shiftKey && /^Digit[1-9]$/.test(e.code) && +e.code.slice(5) <= N) { view.mode = 2; view.which = +e.code.slice(5) - 1; }
  else if (k === "r" || k === "R") { view.yaw = view.pitch = 0; view.c = [0, 0, 0]; view.fixed = null; }
  else if (k === "p" || k === "P") { replay(); return; }
  else return;
  draw();
});
// Replay the input cameras (and the listed views) in order, interpolating centres and rotations.
function replay() {
  const cams = M.path;
  if (cams.length < 2) return;
  let t0 = null;
  const step = now => {
    if (t0 === null) t0 = now;
    const u = (now - t0) / 1000 * 1.5, k = Math.floor(u);
    if (k >= cams.length - 1) { view.fixed = cams[cams.length - 1]; draw(); return; }
    const a = cams[k], b = cams[k + 1], f = u - k;
    const lerp = (x, y) => x.map((v, i) => v * (1 - f) + y[i] * f);
    view.fixed = { ...a, cam_from_world: lerp(a.cam_from_world, b.cam_from_world) };
    draw(); requestAnimationFrame(step);
  };
  requestAnimationFrame(step);
}
// #view=k shows the k-th listed view exactly (#view=ref the reference); #mode=blend|mni<k>|weight<k>.
if (hash.has("view")) view.fixed = hash.get("view") === "ref" ? M.reference : (M.views[+hash.get("view")] || fail("no view " + hash.get("view")));
const mode = hash.get("mode") || "blend";
if (mode.startsWith("mni")) { view.mode = 1; view.which = +mode.slice(3); }
if (mode.startsWith("weight")) { view.mode = 2; view.which = +mode.slice(6); }
draw();
document.title = "MHI viewer: ready";
