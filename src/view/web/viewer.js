// furfit view: shell textures with precomputed radiance transfer (seed 003), raw WebGL2.
// The data (window.FURFIT, window.FURFIT_TEX) is written by `furfit view`; the lighting
// per frame mirrors src/view/prt.rs (frame_lighting) and src/view/sh.rs (eval, rotate),
// the drawing mirrors src/view/still.rs (which is what the tests compare against).
"use strict";
(function () {
  const statusEl = document.getElementById("status");
  const errors = [];
  function fail(msg) {
    errors.push(String(msg));
    statusEl.textContent = "error: " + errors.join("; ");
    document.title = "furfit view: error";
  }
  window.addEventListener("error", (e) => fail(e.message || e));
  const D = window.FURFIT;
  if (!D || !window.FURFIT_TEX || !window.FURFIT_FIN) { fail("data.js or textures.js did not load"); return; }

  // ---- SH (src/view/sh.rs: same polynomials, same order) ----
  function shEval(x, y, z) {
    const x2 = x * x, y2 = y * y, z2 = z * z;
    return [
      0.2820947917738781,
      0.4886025119029199 * y, 0.4886025119029199 * z, 0.4886025119029199 * x,
      1.0925484305920792 * x * y, 1.0925484305920792 * y * z, 0.31539156525252 * (3 * z2 - 1),
      1.0925484305920792 * x * z, 0.5462742152960396 * (x2 - y2),
      0.5900435899266435 * y * (3 * x2 - y2), 2.890611442640554 * x * y * z,
      0.4570457994644658 * y * (5 * z2 - 1), 0.3731763325901154 * z * (5 * z2 - 3),
      0.4570457994644658 * x * (5 * z2 - 1), 1.445305721320277 * z * (x2 - y2),
      0.5900435899266435 * x * (x2 - 3 * y2),
      2.5033429417967046 * x * y * (x2 - y2), 1.7701307697799305 * y * z * (3 * x2 - y2),
      0.94617469575756 * x * y * (7 * z2 - 1), 0.6690465435572891 * y * z * (7 * z2 - 3),
      0.1057855469152042 * (35 * z2 * z2 - 30 * z2 + 3), 0.6690465435572891 * x * z * (7 * z2 - 3),
      0.47308734787878 * (x2 - y2) * (7 * z2 - 1), 1.7701307697799305 * x * z * (x2 - 3 * y2),
      0.6258357354491761 * (x2 * (x2 - 3 * y2) - y2 * (3 * x2 - y2)),
    ];
  }
  const RULE = D.rot_rule.dirs.map((d, i) => ({ y: null, d, w: D.rot_rule.weights[i] }));
  for (const q of RULE) q.y = shEval(q.d[0], q.d[1], q.d[2]);
  const matVec = (r, d) => [0, 1, 2].map((i) => r[i][0] * d[0] + r[i][1] * d[1] + r[i][2] * d[2]);
  const transpose = (r) => [0, 1, 2].map((i) => [r[0][i], r[1][i], r[2][i]]);
  // Coefficients of f(r^T d): exact re-projection on the 5x10 rule (sh.rs rotate).
  function shRotate(c, r) {
    const rt = transpose(r), out = new Float64Array(25);
    for (const q of RULE) {
      const p = matVec(rt, q.d), y = shEval(p[0], p[1], p[2]);
      let f = 0;
      for (let k = 0; k < 25; k++) f += c[k] * y[k];
      f *= q.w;
      for (let k = 0; k < 25; k++) out[k] += f * q.y[k];
    }
    return out;
  }
  function orientation(elev, azim) { // lights.rs orientation: R_y(azim) R_x(90 - elev)
    const t = (90 - elev) * Math.PI / 180, a = azim * Math.PI / 180;
    const se = Math.sin(t), ce = Math.cos(t), sa = Math.sin(a), ca = Math.cos(a);
    const rx = [[1, 0, 0], [0, ce, -se], [0, se, ce]], ry = [[ca, 0, sa], [0, 1, 0], [-sa, 0, ca]];
    return [0, 1, 2].map((i) => [0, 1, 2].map((j) => ry[i][0] * rx[0][j] + ry[i][1] * rx[1][j] + ry[i][2] * rx[2][j]));
  }
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const scl = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const len = (a) => Math.sqrt(dot(a, a));
  const norm = (a) => scl(a, 1 / len(a));
  function fiberFrame(wo, u) { // prt.rs fiber_frame
    let v = sub(wo, scl(u, dot(wo, u)));
    if (len(v) < 1e-9) { v = cross(u, [0, 0, 1]); if (len(v) < 1e-9) v = cross(u, [1, 0, 0]); }
    v = norm(v);
    return [v, cross(u, v), u];
  }
  function b64(s) {
    const bin = atob(s), out = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return out;
  }
  for (const sp of D.species) sp.M = new Float32Array(b64(sp.m).buffer);
  // prt.rs frame_lighting: light into the fiber frame, times B(theta_o), back.
  function frameLighting(sp, light, wo, u) {
    const r = fiberFrame(wo, u), rt = transpose(r), n = sp.n_o;
    const to = Math.asin(Math.max(-1, Math.min(1, dot(wo, u))));
    const f = Math.max(0, Math.min(n - 1, (to + Math.PI / 2) / (Math.PI / n) - 0.5));
    const o0 = Math.min(n - 1, Math.floor(f)), o1 = Math.min(n - 1, o0 + 1), a = f - o0;
    return [0, 1, 2].map((c) => {
      const l = shRotate(light[c], r), out = new Float64Array(25);
      const b0 = (c * n + o0) * 625, b1 = (c * n + o1) * 625;
      for (let j = 0; j < 25; j++) {
        let s = 0;
        for (let k = 0; k < 25; k++) {
          const m0 = sp.M[b0 + j * 25 + k], m1 = sp.M[b1 + j * 25 + k];
          s += (m0 + a * (m1 - m0)) * l[k];
        }
        out[j] = s;
      }
      return shRotate(out, rt);
    });
  }

  // ---- state: URL hash overrides (tests, screenshots) ----
  const hash = new URLSearchParams(location.hash.slice(1));
  const num = (k, d) => (hash.has(k) ? Number(hash.get(k)) : d);
  const pair = (k, d) => (hash.has(k) ? hash.get(k).split(",").map(Number) : d);
  const st = {
    species: Math.min(D.species.length - 1, num("species", 0)),
    light: Math.max(0, D.lights.findIndex((l) => l.name === (hash.get("light") || D.lights[0].name))),
    cam: pair("cam", [D.view.elev, D.view.azim]),
    dist: num("dist", D.view.dist),
    exposure: num("ev", D.view.exposure),
    lightDir: null,
    fins: hash.get("fins") !== "0",
  };
  st.lightDir = pair("lightdir", [D.lights[st.light].elev, D.lights[st.light].azim]);
  const showUi = hash.get("ui") !== "0";

  // ---- WebGL2 ----
  const canvas = document.getElementById("view");
  const W = num("w", window.innerWidth), H = num("h", window.innerHeight);
  canvas.width = W; canvas.height = H;
  canvas.style.width = W + "px"; canvas.style.height = H + "px";
  const gl = canvas.getContext("webgl2", { antialias: false, preserveDrawingBuffer: true, premultipliedAlpha: false, alpha: false });
  if (!gl) { fail("WebGL2 is not available"); return; }
  if (!gl.getExtension("EXT_color_buffer_float")) { fail("EXT_color_buffer_float is not available"); return; }
  function program(vs, fs) {
    const p = gl.createProgram();
    for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
      const s = gl.createShader(type);
      gl.shaderSource(s, src); gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error("shader: " + gl.getShaderInfoLog(s));
      gl.attachShader(p, s);
    }
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error("link: " + gl.getProgramInfoLog(p));
    const u = {};
    const n = gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS);
    for (let i = 0; i < n; i++) { const a = gl.getActiveUniform(p, i); u[a.name.replace("[0]", "")] = gl.getUniformLocation(p, a.name); }
    return { p, u };
  }
  const FULL_VS = `#version 300 es
  out vec2 ndc;
  void main() { vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2)) * 2.0 - 1.0; ndc = p; gl_Position = vec4(p, 0.0, 1.0); }`;
  const SH_GLSL = `
  void shEval(vec3 d, out float y[25]) {
    float x = d.x, yy = d.y, z = d.z, x2 = x*x, y2 = yy*yy, z2 = z*z;
    y[0]=0.2820948; y[1]=0.4886025*yy; y[2]=0.4886025*z; y[3]=0.4886025*x;
    y[4]=1.0925484*x*yy; y[5]=1.0925484*yy*z; y[6]=0.3153916*(3.0*z2-1.0); y[7]=1.0925484*x*z; y[8]=0.5462742*(x2-y2);
    y[9]=0.5900436*yy*(3.0*x2-y2); y[10]=2.8906114*x*yy*z; y[11]=0.4570458*yy*(5.0*z2-1.0); y[12]=0.3731763*z*(5.0*z2-3.0);
    y[13]=0.4570458*x*(5.0*z2-1.0); y[14]=1.4453057*z*(x2-y2); y[15]=0.5900436*x*(x2-3.0*y2);
    y[16]=2.5033429*x*yy*(x2-y2); y[17]=1.7701308*yy*z*(3.0*x2-y2); y[18]=0.9461747*x*yy*(7.0*z2-1.0); y[19]=0.6690465*yy*z*(7.0*z2-3.0);
    y[20]=0.1057855*(35.0*z2*z2-30.0*z2+3.0); y[21]=0.6690465*x*z*(7.0*z2-3.0); y[22]=0.4730873*(x2-y2)*(7.0*z2-1.0);
    y[23]=1.7701308*x*z*(x2-3.0*y2); y[24]=0.6258357*(x2*(x2-3.0*y2)-y2*(3.0*x2-y2));
  }`;
  const BG = program(FULL_VS, `#version 300 es
  precision highp float;
  in vec2 ndc; out vec4 o;
  uniform vec3 uF, uR, uU; uniform float uTan, uAspect, uShow; uniform float uL[75];
  ${SH_GLSL}
  void main() {
    vec3 d = normalize(uF + uR * (ndc.x * uTan * uAspect) + uU * (ndc.y * uTan));
    float y[25]; shEval(d, y);
    vec3 c = vec3(0.0);
    for (int k = 0; k < 25; k++) c += vec3(uL[k], uL[25 + k], uL[50 + k]) * y[k];
    o = vec4(c * uShow, 1.0);
  }`);
  // The lighting of the four picture corners (top-left, top-right, bottom-left,
  // bottom-right; each for its own view direction), blended bilinearly per fragment:
  // still.rs corner_lighting / corner_weights. Corner q's coefficients times the shell's
  // scale are uCR[7 q + j] (texture j's four channels), its offsets' sum uB[q].
  const CORNER_GLSL = `uniform vec4 uCR[28], uCG[28], uCB[28]; uniform vec3 uB[4]; uniform vec2 uVP;
  vec3 radiance(vec4 q[7]) {
    float sx = gl_FragCoord.x / uVP.x, sy = 1.0 - gl_FragCoord.y / uVP.y;
    vec4 w = vec4((1.0 - sx) * (1.0 - sy), sx * (1.0 - sy), (1.0 - sx) * sy, sx * sy);
    vec3 c = vec3(0.0);
    for (int k = 0; k < 4; k++) {
      vec3 ck = uB[k];
      for (int j = 0; j < 7; j++) ck += vec3(dot(q[j], uCR[7 * k + j]), dot(q[j], uCG[7 * k + j]), dot(q[j], uCB[7 * k + j]));
      c += w[k] * ck;
    }
    return c;
  }`;
  const SHELL = program(`#version 300 es
  in vec2 pos; uniform mat4 uMVP; uniform float uY; out vec2 xz; out vec3 wp;
  void main() { xz = pos; wp = vec3(pos.x, uY, pos.y); gl_Position = uMVP * vec4(wp, 1.0); }`, `#version 300 es
  precision highp float; precision highp sampler2DArray;
  in vec2 xz; in vec3 wp; out vec4 o;
  uniform sampler2DArray uTex; uniform int uBase; uniform vec3 uEye;
  ${CORNER_GLSL}
  uniform vec2 uAlpha;
  void main() {
    // The coverage first: an empty texel (all four filtered neighbours empty) adds
    // nothing, so it skips the other six fetches (most texels of the upper shells).
    vec4 q[7];
    q[6] = texture(uTex, vec3(xz, float(uBase + 6)));
    float a = uAlpha.x + uAlpha.y * q[6].y;
    if (a <= 0.0) discard;
    // Seen at a slant the slab is thicker: 1 - (1 - a)^(1 / |d_y|) (still.rs slant_alpha).
    float slant = 1.0 / max(abs(normalize(wp - uEye).y), 0.1);
    a = 1.0 - pow(1.0 - clamp(a, 0.0, 1.0), slant);
    for (int j = 0; j < 6; j++) q[j] = texture(uTex, vec3(xz, float(uBase + j)));
    o = vec4(radiance(q) * a, a);
  }`);
  // Fins (src/view/fins.rs): one strip per shell band of each border wall, coverage from
  // the fin texture, radiance of that band's shell at the fragment's place.
  const FIN = program(`#version 300 es
  in vec2 pos; uniform mat4 uMVP; uniform int uAxis; uniform float uC, uE, uY0, uY1; out vec3 wp;
  void main() {
    float along = -uE + (1.0 + 2.0 * uE) * pos.x, y = uY0 + (uY1 - uY0) * pos.y;
    wp = uAxis == 0 ? vec3(uC, y, along) : vec3(along, y, uC);
    gl_Position = uMVP * vec4(wp, 1.0);
  }`, `#version 300 es
  precision highp float; precision highp int; precision highp sampler2DArray;
  in vec3 wp; out vec4 o;
  uniform sampler2DArray uTex, uFin; uniform int uBase, uAxis, uWall; uniform vec3 uEye, uN;
  uniform float uH, uMinCos;
  ${CORNER_GLSL}
  void main() {
    float along = uAxis == 0 ? wp.z : wp.x;
    float cov = texture(uFin, vec3(along, wp.y / uH, float(uWall))).r;
    if (cov <= 0.0) discard;
    float fv = abs(dot(normalize(wp - uEye), uN));
    float a = smoothstep(0.15, 0.5, fv) * (1.0 - pow(1.0 - clamp(cov, 0.0, 1.0), 1.0 / max(fv, uMinCos)));
    if (a <= 0.0) discard;
    vec4 q[7];
    for (int j = 0; j < 7; j++) q[j] = texture(uTex, vec3(wp.x, wp.z, float(uBase + j)));
    o = vec4(radiance(q) * a, a);
  }`);
  const TONE = program(FULL_VS, `#version 300 es
  precision highp float;
  in vec2 ndc; out vec4 o; uniform sampler2D uImg; uniform float uK;
  float aces(float x) { x = max(x, 0.0); return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0); }
  float srgb(float x) { x = clamp(x, 0.0, 1.0); return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055; }
  void main() { vec3 c = texelFetch(uImg, ivec2(gl_FragCoord.xy), 0).rgb * uK; o = vec4(srgb(aces(c.r)), srgb(aces(c.g)), srgb(aces(c.b)), 1.0); }`);

  const tex = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  gl.texImage3D(gl.TEXTURE_2D_ARRAY, 0, gl.RGBA8, D.res, D.res, D.shells * 7, 0, gl.RGBA, gl.UNSIGNED_BYTE, b64(window.FURFIT_TEX));
  window.FURFIT_TEX = null;
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_S, gl.REPEAT);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_T, gl.REPEAT);
  const finTex = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D_ARRAY, finTex);
  gl.texImage3D(gl.TEXTURE_2D_ARRAY, 0, gl.R8, D.res, D.fins.rows, 4, 0, gl.RED, gl.UNSIGNED_BYTE, b64(window.FURFIT_FIN));
  window.FURFIT_FIN = null;
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_S, gl.REPEAT);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  const img = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, img);
  gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA16F, W, H);
  const fbo = gl.createFramebuffer();
  gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, img, 0);
  if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) { fail("float framebuffer incomplete"); return; }
  const e = D.extent, quad = new Float32Array([-e, -e, 1 + e, -e, -e, 1 + e, 1 + e, 1 + e]);
  const vbo = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, vbo);
  gl.bufferData(gl.ARRAY_BUFFER, quad, gl.STATIC_DRAW);
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  const loc = gl.getAttribLocation(SHELL.p, "pos");
  gl.enableVertexAttribArray(loc);
  gl.vertexAttribPointer(loc, 2, gl.FLOAT, false, 0, 0);
  const finVbo = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, finVbo);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([0, 0, 1, 0, 0, 1, 1, 1]), gl.STATIC_DRAW);
  const finVao = gl.createVertexArray();
  gl.bindVertexArray(finVao);
  const finLoc = gl.getAttribLocation(FIN.p, "pos");
  gl.enableVertexAttribArray(finLoc);
  gl.vertexAttribPointer(finLoc, 2, gl.FLOAT, false, 0, 0);

  // render::scene::Camera::look_at
  function camera() {
    const el = st.cam[0] * Math.PI / 180, az = st.cam[1] * Math.PI / 180, t = D.target;
    const eye = [t[0] + Math.sin(az) * Math.cos(el) * st.dist, t[1] + Math.sin(el) * st.dist, t[2] + Math.cos(az) * Math.cos(el) * st.dist];
    const f = norm(sub(t, eye)), r = norm(cross(f, [0, 1, 0])), u = cross(r, f);
    return { eye, f, r, u, tan: Math.tan(D.view.fov * Math.PI / 360) };
  }
  function mvp(c) { // column-major projection * view, depth unused
    const aspect = W / H, n = 0.01, fa = 100;
    const P = [1 / (c.tan * aspect), 0, 0, 0, 0, 1 / c.tan, 0, 0, 0, 0, -(fa + n) / (fa - n), -1, 0, 0, -2 * fa * n / (fa - n), 0];
    const V = [c.r[0], c.u[0], -c.f[0], 0, c.r[1], c.u[1], -c.f[1], 0, c.r[2], c.u[2], -c.f[2], 0,
      -dot(c.r, c.eye), -dot(c.u, c.eye), dot(c.f, c.eye), 1];
    const M = new Float32Array(16);
    for (let i = 0; i < 4; i++) for (let j = 0; j < 4; j++) {
      let s = 0; for (let k = 0; k < 4; k++) s += P[k * 4 + i] * V[j * 4 + k]; M[j * 4 + i] = s;
    }
    return M;
  }
  function shellOrder(eyeY) { // still.rs shell_order
    const below = [], above = [];
    for (let s = 0; s < D.shells; s++) if (D.shell_y[s] < eyeY) below.push(s);
    for (let s = D.shells - 1; s >= 0; s--) if (D.shell_y[s] >= eyeY) above.push(s);
    return below.concat(above);
  }
  function wallOrder(eye, wantBack) { // fins.rs order: the back walls or the front ones
    const back = (w) => ((w.axis === 0 ? eye[0] : eye[2]) - w.c) * w.sign < 0;
    return [0, 1, 2, 3].filter((i) => back(D.fins.walls[i]) === wantBack);
  }
  function drawFins(c, coef, walls) {
    gl.useProgram(FIN.p);
    gl.bindVertexArray(finVao);
    gl.activeTexture(gl.TEXTURE0); gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex);
    gl.activeTexture(gl.TEXTURE2); gl.bindTexture(gl.TEXTURE_2D_ARRAY, finTex);
    gl.uniform1i(FIN.u.uTex, 0); gl.uniform1i(FIN.u.uFin, 2);
    gl.uniformMatrix4fv(FIN.u.uMVP, false, mvp(c));
    gl.uniform3fv(FIN.u.uEye, c.eye);
    gl.uniform2f(FIN.u.uVP, W, H);
    gl.uniform1f(FIN.u.uE, D.extent); gl.uniform1f(FIN.u.uH, D.height); gl.uniform1f(FIN.u.uMinCos, D.slant_min_cos);
    // Fins and shells are drawn back to front with "over" blending: back walls, shells, front walls.
    for (const w of walls) {
      const wall = D.fins.walls[w];
      gl.uniform1i(FIN.u.uWall, w); gl.uniform1i(FIN.u.uAxis, wall.axis); gl.uniform1f(FIN.u.uC, wall.c);
      gl.uniform3fv(FIN.u.uN, wall.axis === 0 ? [wall.sign, 0, 0] : [0, 0, wall.sign]);
      for (let s = 0; s < D.shells; s++) {
        const { cr, cg, cb, b } = coef[s];
        gl.uniform4fv(FIN.u.uCR, cr); gl.uniform4fv(FIN.u.uCG, cg); gl.uniform4fv(FIN.u.uCB, cb);
        gl.uniform3fv(FIN.u.uB, b);
        gl.uniform1i(FIN.u.uBase, s * 7);
        gl.uniform1f(FIN.u.uY0, s * D.dy); gl.uniform1f(FIN.u.uY1, s === D.shells - 1 ? D.height : (s + 1) * D.dy);
        gl.drawArrays(gl.TRIANGLE_STRIP, 0, 4);
      }
    }
  }
  // Draws one frame; returns the milliseconds of its CPU part (SH rotation of the light,
  // the BCSDF matrix product and the per-shell uniforms; the GPU's work is not waited for).
  function draw() {
    const tc = performance.now();
    const c = camera(), sp = D.species[st.species], L = D.lights[st.light];
    const R = orientation(st.lightDir[0], st.lightDir[1]);
    const light = L.coeffs.map((ch) => shRotate(ch, R));
    // The corners' view directions: the reversed rays through them (BG's ray formula).
    const cfs = [[-1, 1], [1, 1], [-1, -1], [1, -1]].map(([x, y]) => {
      const d = norm([0, 1, 2].map((i) => c.f[i] + c.r[i] * (x * c.tan * W / H) + c.u[i] * (y * c.tan)));
      return frameLighting(sp, light, d.map((v) => -v), D.comb);
    });
    const cpuMs = performance.now() - tc;
    gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
    gl.viewport(0, 0, W, H);
    gl.disable(gl.BLEND);
    gl.useProgram(BG.p);
    gl.uniform3fv(BG.u.uF, c.f); gl.uniform3fv(BG.u.uR, c.r); gl.uniform3fv(BG.u.uU, c.u);
    gl.uniform1f(BG.u.uTan, c.tan); gl.uniform1f(BG.u.uAspect, W / H); gl.uniform1f(BG.u.uShow, 1.0);
    gl.uniform1fv(BG.u.uL, new Float32Array([...light[0], ...light[1], ...light[2]]));
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    gl.enable(gl.BLEND);
    gl.blendFunc(gl.ONE, gl.ONE_MINUS_SRC_ALPHA);
    // Per shell: the frame's lighting times the shell's dequantisation (scale, offset).
    const coef = [];
    for (let s = 0; s < D.shells; s++) {
      const cr = new Float32Array(112), cg = new Float32Array(112), cb = new Float32Array(112), b = new Float32Array(12);
      cfs.forEach((cf, q) => {
        for (let k = 0; k < 25; k++) {
          const sc = D.scale[s * 28 + k], of = D.offset[s * 28 + k];
          cr[28 * q + k] = cf[0][k] * sc; cg[28 * q + k] = cf[1][k] * sc; cb[28 * q + k] = cf[2][k] * sc;
          b[3 * q] += cf[0][k] * of; b[3 * q + 1] += cf[1][k] * of; b[3 * q + 2] += cf[2][k] * of;
        }
      });
      coef.push({ cr, cg, cb, b });
    }
    if (st.fins) drawFins(c, coef, wallOrder(c.eye, true));
    gl.useProgram(SHELL.p);
    gl.bindVertexArray(vao);
    gl.activeTexture(gl.TEXTURE0); gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex);
    gl.uniform1i(SHELL.u.uTex, 0);
    gl.uniformMatrix4fv(SHELL.u.uMVP, false, mvp(c));
    gl.uniform3fv(SHELL.u.uEye, c.eye);
    gl.uniform2f(SHELL.u.uVP, W, H);
    for (const s of shellOrder(c.eye[1])) {
      const { cr, cg, cb, b } = coef[s];
      gl.uniform4fv(SHELL.u.uCR, cr); gl.uniform4fv(SHELL.u.uCG, cg); gl.uniform4fv(SHELL.u.uCB, cb);
      gl.uniform3fv(SHELL.u.uB, b);
      gl.uniform2f(SHELL.u.uAlpha, D.offset[s * 28 + 25], D.scale[s * 28 + 25]);
      gl.uniform1i(SHELL.u.uBase, s * 7);
      gl.uniform1f(SHELL.u.uY, D.shell_y[s]);
      gl.drawArrays(gl.TRIANGLE_STRIP, 0, 4);
    }
    if (st.fins) drawFins(c, coef, wallOrder(c.eye, false));
    gl.disable(gl.BLEND);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.useProgram(TONE.p);
    gl.activeTexture(gl.TEXTURE1); gl.bindTexture(gl.TEXTURE_2D, img);
    gl.uniform1i(TONE.u.uImg, 1); gl.uniform1f(TONE.u.uK, Math.pow(2, st.exposure));
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    return cpuMs;
  }

  // ---- UI ----
  const info = document.getElementById("info"), fps = document.getElementById("fps");
  const selS = document.getElementById("species"), selL = document.getElementById("light");
  D.species.forEach((s, i) => selS.add(new Option(s.name + " (" + s.model + ")", i)));
  D.lights.forEach((l, i) => selL.add(new Option(l.label, i)));
  selS.value = st.species; selL.value = st.light;
  const chkF = document.getElementById("fins");
  chkF.checked = st.fins;
  chkF.onchange = () => { st.fins = chkF.checked; redraw(); };
  function showInfo() {
    const s = D.species[st.species];
    info.textContent = s.name + "\n" + s.model + ": " + s.title + "\n" + s.params.join("\n") + "\ncolour: " + s.colour;
  }
  if (!showUi) for (const id of ["ui", "status", "bench"]) document.getElementById(id).style.visibility = "hidden";
  // Frame time: each frame is drawn and then waited for (a one-pixel readPixels), so the
  // figure is the whole frame, CPU lighting and GPU drawing. The first frame (shader
  // compilation, texture upload) is reported apart. window.furfitFrameMs holds the mean
  // of the last frames, window.furfitFrame the details (tests and bench/view read them).
  const recent = [];
  let pending = false, nFrames = 0;
  window.furfitFrame = { first_ms: null, last_ms: null, cpu_ms: null, frames: 0, width: W, height: H, shells: D.shells };
  window.furfitFrameMs = null;
  function timedFrame() {
    const t0 = performance.now();
    const cpu = draw();
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4)); // wait for the GPU
    const ms = performance.now() - t0;
    const f = window.furfitFrame;
    nFrames += 1; f.frames = nFrames; f.last_ms = ms; f.cpu_ms = cpu;
    if (nFrames === 1) f.first_ms = ms;
    else { recent.push(ms); if (recent.length > 30) recent.shift(); }
    const mean = recent.length ? recent.reduce((a, b) => a + b, 0) / recent.length : ms;
    window.furfitFrameMs = mean;
    fps.textContent = (recent.length ? "frame " + mean.toFixed(1) + " ms (mean of " + recent.length + ")"
      : "first frame " + ms.toFixed(0) + " ms (with shader compilation)") + ", CPU lighting " + cpu.toFixed(2) + " ms";
    return ms;
  }
  function frame() { pending = false; timedFrame(); }
  function redraw() { if (!pending) { pending = true; requestAnimationFrame(frame); } }
  selS.onchange = () => { st.species = Number(selS.value); showInfo(); redraw(); };
  selL.onchange = () => { st.light = Number(selL.value); const l = D.lights[st.light]; st.lightDir = [l.elev, l.azim]; redraw(); };
  let drag = null;
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener("pointerdown", (e) => { drag = { x: e.clientX, y: e.clientY, light: e.button === 2 || e.shiftKey }; canvas.setPointerCapture(e.pointerId); });
  canvas.addEventListener("pointerup", () => { drag = null; });
  canvas.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX; drag.y = e.clientY;
    const v = drag.light ? st.lightDir : st.cam;
    v[1] -= dx * 0.4; v[0] = Math.max(drag.light ? -89 : 5, Math.min(89.9, v[0] + dy * 0.4));
    redraw();
  });
  canvas.addEventListener("wheel", (e) => { e.preventDefault(); st.dist = Math.max(0.5, Math.min(10, st.dist * Math.exp(e.deltaY * 0.001))); redraw(); }, { passive: false });

  showInfo();
  frame();
  // Benchmark: #bench=N draws N frames back to back (the camera turning half a degree a
  // frame) after the first and reports their mean, also as window.furfitBench.
  if (hash.has("bench")) {
    const n = Math.max(1, Number(hash.get("bench")));
    const times = [], cpus = [];
    for (let i = 0; i < n; i++) { st.cam[1] += 0.5; times.push(timedFrame()); cpus.push(window.furfitFrame.cpu_ms); }
    const mean = (v) => v.reduce((a, b) => a + b, 0) / v.length;
    const sorted = times.slice().sort((a, b) => a - b);
    const b = window.furfitBench = {
      width: W, height: H, shells: D.shells, res: D.res, frames: n,
      first_ms: window.furfitFrame.first_ms, mean_ms: mean(times), median_ms: sorted[Math.floor(n / 2)],
      min_ms: sorted[0], max_ms: sorted[n - 1], cpu_ms: mean(cpus),
      renderer: (() => { const x = gl.getExtension("WEBGL_debug_renderer_info"); return x ? gl.getParameter(x.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER); })(),
    };
    document.getElementById("bench").textContent = "bench " + JSON.stringify(b);
  }
  if (errors.length === 0) { statusEl.textContent = "ready"; document.title = "furfit view: ready"; }
})();
