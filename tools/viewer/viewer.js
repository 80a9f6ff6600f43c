// bodymodel viewer (written by `bodymodel viewer`): three.js draws, our own GLSL skins.
// Data: window.VIEWER_DATA (viewer_data.js), base64 little-endian float32 / uint32 arrays.
'use strict';
(function () {
const D = window.VIEWER_DATA;
const f32 = (s) => new Float32Array(Uint8Array.from(atob(s), (c) => c.charCodeAt(0)).buffer);
const u32 = (s) => new Uint32Array(Uint8Array.from(atob(s), (c) => c.charCodeAt(0)).buffer);
const TEX_W = 4096;
const METHODS = { ssd: 0, as: 1, mwe: 2 };

// The skinning evaluator, shared by the drawn mesh and the transform-feedback read-back, so the
// test reads back exactly what is drawn. Rig texels per (vertex, slot): (bone, c0, c1, c2)
// (c3..c6) (c7..c10) (c11, -, -, -); bone maps: 3 texels per (frame, bone) = rows of [R t].
//   ssd: v' = sum_k w_k M_k [v;1]      as: v' = sum_k M_k p_k
//   mwe: v'_j = sum_k sum_i W_k[j][i] (M_k)_ji [v;1]_i      (skinning/skinning_rig.h)
const SKIN_GLSL = `
precision highp float; precision highp int; precision highp sampler2D;
uniform sampler2D uBones; uniform int uFrame; uniform int uBoneCount;
vec4 fetch(sampler2D t, int i) { int w = textureSize(t, 0).x; return texelFetch(t, ivec2(i % w, i / w), 0); }
vec3 skin(sampler2D rig, int K, int method, int vid, vec3 rest) {
  vec4 p = vec4(rest, 1.0);
  vec3 o = vec3(0.0);
  for (int k = 0; k < K; ++k) {
    int base = (vid * K + k) * 4;
    vec4 t0 = fetch(rig, base);
    if (t0.x < -0.5) continue;
    int mb = (uFrame * uBoneCount + int(t0.x + 0.5)) * 3;
    vec4 r0 = fetch(uBones, mb), r1 = fetch(uBones, mb + 1), r2 = fetch(uBones, mb + 2);
    if (method == 0) {
      o += t0.y * vec3(dot(r0, p), dot(r1, p), dot(r2, p));
    } else if (method == 1) {
      vec4 q = vec4(t0.yzw, fetch(rig, base + 1).x);
      o += vec3(dot(r0, q), dot(r1, q), dot(r2, q));
    } else {
      vec4 t1 = fetch(rig, base + 1), t2 = fetch(rig, base + 2), t3 = fetch(rig, base + 3);
      vec4 w0 = vec4(t0.yzw, t1.x), w1 = vec4(t1.yzw, t2.x), w2 = vec4(t2.yzw, t3.x);
      o += vec3(dot(w0 * r0, p), dot(w1 * r1, p), dot(w2 * r2, p));
    }
  }
  return o;
}`;

function texData(data) {  // RGBA float rows of TEX_W texels
  const texels = Math.ceil(data.length / 4);
  const h = Math.max(1, Math.ceil(texels / TEX_W));
  const out = new Float32Array(TEX_W * h * 4);
  out.set(data);
  return { data: out, w: TEX_W, h };
}

const state = { ready: false, frame: 0, playing: true, framesDrawn: 0, rig: 0, reference: 0, errorMap: false,
                errScale: D.error_scale || 20, mesh: -1, legend: false };
window.viewerState = state;

const canvas = document.getElementById('view');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.setClearColor(0xffffff, 1);
const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(30, 1, 1, 1e6);

const rigs = (D.rigs || []).map((r) => {
  const t = texData(f32(r.texels));
  const tex = new THREE.DataTexture(t.data, t.w, t.h, THREE.RGBAFormat, THREE.FloatType);
  tex.needsUpdate = true;
  return { name: r.name, method: METHODS[r.method], K: r.K, raw: t, tex };
});
let bonesRaw = null, bonesTex = null;
if (rigs.length) {
  bonesRaw = texData(f32(D.transforms));
  bonesTex = new THREE.DataTexture(bonesRaw.data, bonesRaw.w, bonesRaw.h, THREE.RGBAFormat, THREE.FloatType);
  bonesTex.needsUpdate = true;
}

const VERT = SKIN_GLSL + `
uniform mat4 modelViewMatrix; uniform mat4 projectionMatrix;
uniform sampler2D uRig; uniform int uK; uniform int uMethod;
uniform sampler2D uRef; uniform int uRefK; uniform int uRefMethod; uniform int uErrorMap;
in vec3 position;
out vec3 vView; out float vErr;
void main() {
  vec3 x = skin(uRig, uK, uMethod, gl_VertexID, position);
  vErr = uErrorMap == 1 ? distance(x, skin(uRef, uRefK, uRefMethod, gl_VertexID, position)) : -1.0;
  vec4 mv = modelViewMatrix * vec4(x, 1.0);
  vView = mv.xyz;
  gl_Position = projectionMatrix * mv;
}`;
const FRAG = `
precision highp float;
uniform float uErrScale;
in vec3 vView; in float vErr;
out vec4 color;
vec3 ramp(float t) { return clamp(vec3(1.5 - abs(4.0 * t - 3.0), 1.5 - abs(4.0 * t - 2.0), 1.5 - abs(4.0 * t - 1.0)), 0.0, 1.0); }
void main() {
  vec3 n = normalize(cross(dFdx(vView), dFdy(vView)));  // flat shading: no normals to skin
  float l = 0.35 + 0.65 * abs(n.z);
  vec3 base = vErr < 0.0 ? vec3(0.78, 0.72, 0.66) : ramp(clamp(vErr / uErrScale, 0.0, 1.0));
  color = vec4(base * l, 1.0);
}`;
// Static meshes: err = the vertex's distance to the mesh's reference (mm), −1 = no error map.
const STATIC_VERT = `
precision highp float;
uniform mat4 modelViewMatrix; uniform mat4 projectionMatrix;
in vec3 position; in float err; out vec3 vView; out float vErr;
void main() { vec4 mv = modelViewMatrix * vec4(position, 1.0); vView = mv.xyz; vErr = err; gl_Position = projectionMatrix * mv; }`;
const staticScale = { value: state.errScale };  // one uniform shared by every static mesh

let skinned = null;
if (rigs.length) {
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(f32(D.rest), 3));
  g.setIndex(new THREE.BufferAttribute(u32(D.faces), 1));
  const m = new THREE.RawShaderMaterial({
    glslVersion: THREE.GLSL3, vertexShader: VERT, fragmentShader: FRAG, side: THREE.DoubleSide,
    uniforms: { uBones: { value: bonesTex }, uFrame: { value: 0 }, uBoneCount: { value: D.bone_count },
                uRig: { value: rigs[0].tex }, uK: { value: rigs[0].K }, uMethod: { value: rigs[0].method },
                uRef: { value: rigs[0].tex }, uRefK: { value: rigs[0].K }, uRefMethod: { value: rigs[0].method },
                uErrorMap: { value: 0 }, uErrScale: { value: state.errScale } } });
  skinned = new THREE.Mesh(g, m);
  skinned.frustumCulled = false;  // the shader moves the vertices; the rest bounds do not hold
  scene.add(skinned);
}
const statics = (D.meshes || []).map((s) => {
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(f32(s.positions), 3));
  g.setIndex(new THREE.BufferAttribute(u32(s.faces), 1));
  const n = g.getAttribute('position').count;
  g.setAttribute('err', new THREE.BufferAttribute(s.errors ? f32(s.errors) : new Float32Array(n).fill(-1), 1));
  g.computeBoundingBox();
  const m = new THREE.RawShaderMaterial({ glslVersion: THREE.GLSL3, vertexShader: STATIC_VERT, fragmentShader: FRAG,
                                          side: THREE.DoubleSide, uniforms: { uErrScale: staticScale } });
  const mesh = new THREE.Mesh(g, m);
  mesh.visible = false;
  scene.add(mesh);
  return { name: s.errors ? s.name + ' (error vs ' + s.reference + ')' : s.name, mesh, box: g.boundingBox,
           errors: !!s.errors, mean: s.error_mean, max: s.error_max, reference: s.reference };
});
// A marker capture (D.markers): points playing over time at the capture's rate; per sample a state,
// 0 seen, 1 filled by the cleaning (drawn in orange), 2 missing (not drawn).
const MARKER_VERT = `
precision highp float;
uniform mat4 modelViewMatrix; uniform mat4 projectionMatrix; uniform float uSize;
in vec3 position; in float state; out float vState;
void main() {
  vState = state;
  gl_Position = state > 1.5 ? vec4(2.0, 2.0, 2.0, 1.0) : projectionMatrix * modelViewMatrix * vec4(position, 1.0);
  gl_PointSize = uSize;
}`;
const MARKER_FRAG = `
precision highp float;
in float vState; out vec4 color;
void main() {
  if (vState > 1.5) discard;
  color = vec4(vState > 0.5 ? vec3(0.95, 0.42, 0.05) : vec3(0.2, 0.32, 0.62), 1.0);
}`;
const markers = D.markers ? (() => {
  const M = D.markers, pos = f32(M.positions), st = Uint8Array.from(atob(M.state), (c) => c.charCodeAt(0));
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * M.count), 3));
  g.setAttribute('state', new THREE.BufferAttribute(new Float32Array(M.count).fill(2), 1));
  const box = new THREE.Box3(), p = new THREE.Vector3();
  for (let i = 0; i < st.length; ++i) if (st[i] < 2) box.expandByPoint(p.set(pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]));
  const material = new THREE.RawShaderMaterial({ glslVersion: THREE.GLSL3, vertexShader: MARKER_VERT,
                                                 fragmentShader: MARKER_FRAG, uniforms: { uSize: { value: 6 } } });
  const points = new THREE.Points(g, material);
  points.frustumCulled = false;  // the positions change every frame
  points.visible = false;
  scene.add(points);
  return { M, pos, st, g, box, points, frame: -1, playing: true };
})() : null;
state.markerFrame = 0;
function setMarkerFrame(f) {  // copies frame f's positions and states into the drawn points
  if (!markers || markers.frame === f) return;
  const n = markers.M.count, P = markers.g.getAttribute('position'), S = markers.g.getAttribute('state');
  P.array.set(markers.pos.subarray(3 * n * f, 3 * n * (f + 1)));
  let filled = 0, missing = 0;
  for (let i = 0; i < n; ++i) {
    const s = markers.st[n * f + i];
    S.array[i] = s; filled += s === 1; missing += s === 2;
  }
  P.needsUpdate = true; S.needsUpdate = true;
  markers.frame = f; state.markerFrame = f;
  document.getElementById('markerText').textContent =
    `frame ${f + 1} / ${markers.M.frames}: ${n - missing} of ${n} markers, ${filled} filled`;
}

// "All meshes side by side" (e.g. the crowd): laid out along x with a gap of a tenth of the widest.
const layout = (() => {
  const widest = Math.max(0, ...statics.map((s) => s.box.max.x - s.box.min.x));
  let x = 0;
  return statics.map((s) => { const dx = x - s.box.min.x; x += s.box.max.x - s.box.min.x + 0.1 * widest; return dx; });
})();

const el = (id) => document.getElementById(id);
// Orbit: drag turns, wheel zooms, around the centre of what is shown.
const orbit = { az: 0.4, el: 0.15, dist: 1, target: new THREE.Vector3() };
function frameObject(box) {
  box.getCenter(orbit.target);
  const s = box.getSize(new THREE.Vector3());
  orbit.dist = 2.2 * Math.max(s.x, s.y, s.z);
}
function placeCamera() {
  const c = Math.cos(orbit.el);
  camera.position.set(orbit.target.x + orbit.dist * c * Math.sin(orbit.az), orbit.target.y + orbit.dist * Math.sin(orbit.el),
                      orbit.target.z + orbit.dist * c * Math.cos(orbit.az));
  camera.near = orbit.dist / 100; camera.far = orbit.dist * 100;
  camera.lookAt(orbit.target);
  camera.updateProjectionMatrix();
}
let drag = null;
canvas.addEventListener('pointerdown', (e) => { drag = [e.clientX, e.clientY]; canvas.setPointerCapture(e.pointerId); });
canvas.addEventListener('pointerup', () => { drag = null; });
canvas.addEventListener('pointermove', (e) => {
  if (!drag) return;
  orbit.az -= (e.clientX - drag[0]) * 0.01;
  orbit.el = Math.max(-1.5, Math.min(1.5, orbit.el + (e.clientY - drag[1]) * 0.01));
  drag = [e.clientX, e.clientY];
});
canvas.addEventListener('wheel', (e) => { e.preventDefault(); orbit.dist *= Math.exp(e.deltaY * 0.001); }, { passive: false });

function show(meshIndex) {  // -1: the skinned rig, -2: every static mesh side by side, -3: the markers
  state.mesh = meshIndex;
  if (skinned) skinned.visible = meshIndex === -1;
  if (markers) markers.points.visible = meshIndex === -3;
  statics.forEach((s, i) => {
    s.mesh.visible = meshIndex === -2 || i === meshIndex;
    s.mesh.position.x = meshIndex === -2 ? layout[i] : 0;
  });
  if (meshIndex === -1) {
    const g = skinned.geometry; g.computeBoundingBox(); frameObject(g.boundingBox);
  } else if (meshIndex === -2) {
    const all = new THREE.Box3();
    statics.forEach((s, i) => all.union(s.box.clone().translate(new THREE.Vector3(layout[i], 0, 0))));
    frameObject(all);
  } else if (meshIndex === -3) {
    frameObject(markers.box.clone());
  } else frameObject(statics[meshIndex].box);
  if (rigs.length) el('rigControls').style.display = meshIndex === -1 ? '' : 'none';  // they act on the rig only
  el('markerControls').style.display = meshIndex === -3 ? '' : 'none';
  updateLegend();
}

// The colour map's legend, shown whenever something drawn is coloured by an error.
const rampCss = (t) => [1.5 - Math.abs(4 * t - 3), 1.5 - Math.abs(4 * t - 2), 1.5 - Math.abs(4 * t - 1)]
  .map((c) => Math.round(255 * Math.max(0, Math.min(1, c))));
el('legendBar').style.background = 'linear-gradient(to right, ' +
  Array.from({ length: 9 }, (_, i) => `rgb(${rampCss(i / 8).join(',')})`).join(', ') + ')';
function updateLegend() {
  const s = state.mesh >= 0 ? statics[state.mesh] : null;
  const on = (state.mesh === -1 && state.errorMap) || (s && s.errors) || (state.mesh === -2 && statics.some((x) => x.errors));
  state.legend = !!on;
  el('legend').style.display = on ? 'block' : 'none';
  el('legendTitle').textContent = state.mesh === -1 ? 'vertex distance to ' + rigs[state.reference].name + ' (mm)'
    : s && s.errors ? `vertex distance to ${s.reference}: mean ${s.mean.toFixed(1)}, max ${s.max.toFixed(1)} mm`
    : 'vertex distance to the reference (mm)';
  el('legendMax').textContent = '≥ ' + state.errScale + ' mm';
}

// Controls.
const objSel = el('object');
if (skinned) objSel.add(new Option('animated rig (' + D.clip + ')', '-1'));
statics.forEach((s, i) => objSel.add(new Option(s.name, String(i))));
if (statics.length > 1) objSel.add(new Option('all meshes side by side', '-2'));
if (markers) objSel.add(new Option('markers (' + D.markers.name + ')', '-3'));
objSel.onchange = () => show(Number(objSel.value));
for (const id of ['method', 'reference']) rigs.forEach((r, i) => el(id).add(new Option(r.name, String(i))));
el('reference').value = String(Math.max(0, rigs.findIndex((r) => r.method === 2)));
function applyRig() {
  state.errScale = Number(el('scale').value); staticScale.value = state.errScale;
  el('scaleText').textContent = state.errScale + ' mm';
  updateLegend();
  if (!skinned) return;
  const u = skinned.material.uniforms, r = rigs[Number(el('method').value)], q = rigs[Number(el('reference').value)];
  state.rig = Number(el('method').value); state.reference = Number(el('reference').value);
  u.uRig.value = r.tex; u.uK.value = r.K; u.uMethod.value = r.method;
  u.uRef.value = q.tex; u.uRefK.value = q.K; u.uRefMethod.value = q.method;
  state.errorMap = el('error').checked; u.uErrorMap.value = state.errorMap ? 1 : 0;
  u.uErrScale.value = state.errScale;
  updateLegend();
}
for (const id of ['method', 'reference', 'error', 'scale']) el(id).oninput = applyRig;
el('mplay').onclick = () => {
  markers.playing = !markers.playing; el('mplay').textContent = markers.playing ? 'pause' : 'play';
  markers.t0 = performance.now() - 1000 * state.markerFrame / markers.M.rate;
};
el('play').onclick = () => { state.playing = !state.playing; el('play').textContent = state.playing ? 'pause' : 'play'; };
if (!rigs.length) for (const id of ['rigControls']) el(id).style.display = 'none';

function resize() {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  if (canvas.width !== w || canvas.height !== h) { renderer.setSize(w, h, false); camera.aspect = w / h; }
}
let t0 = performance.now();
function draw() {
  resize();
  placeCamera();
  if (skinned) {
    skinned.material.uniforms.uFrame.value = state.frame;
    el('frameText').textContent = 'frame ' + (state.frame + 1) + ' / ' + D.frames;
  }
  setMarkerFrame(state.markerFrame);
  renderer.render(scene, camera);
  state.framesDrawn++;
}
function step(now) {  // the frames shown at time `now` (ms), drawn
  if (skinned && state.playing) {
    state.frame = Math.floor((now - t0) / 1000 / D.frame_time) % D.frames;
  }
  if (markers && markers.playing) {
    if (markers.t0 === undefined) markers.t0 = now;
    state.markerFrame = Math.floor((now - markers.t0) / 1000 * markers.M.rate) % markers.M.frames;
  }
  draw();
}
function tick(now) {
  step(now);
  requestAnimationFrame(tick);
}

// Read-back for the test: the same skin() through transform feedback in a second WebGL2 context
// (three's state untouched); returns #V*3 positions of rig `ri` at stored frame `frame`.
function readback(ri, frame) {
  const c = document.createElement('canvas');
  const gl = c.getContext('webgl2');
  const sh = (type, src) => {
    const s = gl.createShader(type); gl.shaderSource(s, '#version 300 es\n' + src); gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  };
  const prog = gl.createProgram();
  gl.attachShader(prog, sh(gl.VERTEX_SHADER, SKIN_GLSL + `
uniform sampler2D uRig; uniform int uK; uniform int uMethod;
in vec3 position; out vec3 outPos;
void main() { outPos = skin(uRig, uK, uMethod, gl_VertexID, position); gl_Position = vec4(0.0); }`));
  gl.attachShader(prog, sh(gl.FRAGMENT_SHADER, 'precision highp float; out vec4 c; void main() { c = vec4(0.0); }'));
  gl.transformFeedbackVaryings(prog, ['outPos'], gl.SEPARATE_ATTRIBS);
  gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
  gl.useProgram(prog);
  const tex = (t, unit) => {
    const x = gl.createTexture(); gl.activeTexture(gl.TEXTURE0 + unit); gl.bindTexture(gl.TEXTURE_2D, x);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST); gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, t.w, t.h, 0, gl.RGBA, gl.FLOAT, t.data);
  };
  const r = rigs[ri];
  tex(r.raw, 0); tex(bonesRaw, 1);
  const U = (n) => gl.getUniformLocation(prog, n);
  gl.uniform1i(U('uRig'), 0); gl.uniform1i(U('uBones'), 1); gl.uniform1i(U('uK'), r.K); gl.uniform1i(U('uMethod'), r.method);
  gl.uniform1i(U('uFrame'), frame); gl.uniform1i(U('uBoneCount'), D.bone_count);
  const rest = f32(D.rest), n = rest.length / 3;
  const vb = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, vb); gl.bufferData(gl.ARRAY_BUFFER, rest, gl.STATIC_DRAW);
  const loc = gl.getAttribLocation(prog, 'position'); gl.enableVertexAttribArray(loc); gl.vertexAttribPointer(loc, 3, gl.FLOAT, false, 0, 0);
  const ob = gl.createBuffer(); gl.bindBuffer(gl.TRANSFORM_FEEDBACK_BUFFER, ob); gl.bufferData(gl.TRANSFORM_FEEDBACK_BUFFER, n * 12, gl.STATIC_READ);
  const tf = gl.createTransformFeedback(); gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, tf);
  gl.bindBufferBase(gl.TRANSFORM_FEEDBACK_BUFFER, 0, ob);
  gl.enable(gl.RASTERIZER_DISCARD);
  gl.beginTransformFeedback(gl.POINTS); gl.drawArrays(gl.POINTS, 0, n); gl.endTransformFeedback();
  gl.disable(gl.RASTERIZER_DISCARD);
  gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, null);
  const out = new Float32Array(n * 3);
  gl.bindBuffer(gl.TRANSFORM_FEEDBACK_BUFFER, ob); gl.getBufferSubData(gl.TRANSFORM_FEEDBACK_BUFFER, 0, out);
  gl.getExtension('WEBGL_lose_context')?.loseContext();
  return out;
}

// Hooks for tests/viewer/browser_test.js.
window.viewerApi = {
  rigs: () => rigs.map((r) => r.name),
  meshes: () => statics.map((s) => ({ name: s.name, errors: s.errors })),
  show: (i) => { objSel.value = String(i); show(i); draw(); return state.legend; },
  readback: (ri, frame) => Array.from(readback(ri, frame)),
  // Stop at a frame and draw it now; returns the view-projection matrix (column-major) and size.
  freeze: (frame) => {
    state.playing = false; state.frame = frame; draw();
    const vp = new THREE.Matrix4().multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse);
    return { vp: vp.elements.slice(), width: canvas.width, height: canvas.height };
  },
  play: () => { state.playing = true; t0 = performance.now(); },
  // One step of the play loop at performance.now() (headless virtual time runs timers, not
  // animation frames); returns the marker frame drawn.
  step: () => { step(performance.now()); return state.markerFrame; },
  // The markers shown and stopped at a frame, drawn now; the view-projection matrix and size as freeze.
  showMarkers: (frame) => {
    if (!markers) throw new Error('no markers in this viewer');
    objSel.value = '-3'; show(-3);
    markers.playing = false; state.markerFrame = frame; draw();
    const vp = new THREE.Matrix4().multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse);
    return { vp: vp.elements.slice(), width: canvas.width, height: canvas.height };
  },
  // RGBA pixels of the drawn canvas, rows bottom-up (gl.readPixels), base64.
  pixels: () => {
    const gl = renderer.getContext(), w = canvas.width, h = canvas.height, px = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    let s = ''; for (let i = 0; i < px.length; i += 32768) s += String.fromCharCode.apply(null, px.subarray(i, i + 32768));
    return btoa(s);
  },
};

el('scale').max = String(Math.max(100, state.errScale));
el('scale').value = String(state.errScale);
show(skinned ? -1 : markers && !statics.length ? -3 : 0);
// A view can be linked: index.html?rig=0&reference=1&error=1&frame=12 (frame given: paused there),
// index.html?mesh=2 (a static mesh; -2: all side by side).
const q = new URLSearchParams(location.search);
for (const id of ['rig', 'reference']) if (q.has(id) && rigs[Number(q.get(id))]) el(id === 'rig' ? 'method' : id).value = q.get(id);
if (q.get('error') === '1') el('error').checked = true;
if (q.has('mesh') && (statics[Number(q.get('mesh'))] || (q.get('mesh') === '-2' && statics.length > 1) ||
                      (q.get('mesh') === '-3' && markers))) {
  objSel.value = q.get('mesh'); show(Number(q.get('mesh')));
}
applyRig();
if (skinned && q.has('frame')) {
  state.playing = false; el('play').textContent = 'play';
  state.frame = Math.max(0, Math.min(D.frames - 1, Number(q.get('frame')) || 0));
}
requestAnimationFrame((now) => { t0 = now; state.ready = true; tick(now); });
})();
