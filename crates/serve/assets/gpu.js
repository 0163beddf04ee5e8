// gantry serve — the real-time view: the model's components on the GPU (WebGL2), each fragment
// evaluating f = max(exp(mean + Σ c_j U_j) − floor, 0) from the material's coefficients
// (thesis §7.2.2). The server sends the mean and components on a reduced grid in half floats
// (/api/gpu/basis.bin, layout in docs/formats.md), the light probe, and the coefficients.
// Where WebGL2 is missing the page keeps the server's CPU previews and says so.
'use strict';

(function () {
  const $ = (id) => document.getElementById(id);
  let TH = 0, TD = 0, PD = 0;         // reduced grid (θh, θd, φd bins), from the basis file
  const MAX_K = 64;                   // coefficients the shader takes
  const POINT_FRAMES = 16;            // jittered frames averaged under the point light
  const ENV_SAMPLES = 4;              // environment samples per pixel per frame
  const ENV_FRAMES = 256;             // frames accumulated under the probe (1,024 samples)
  const SPHERE_LIGHT = [-4, 4, 6];    // render::sphere_scene's point light
  const LOBE_BINS = 90;               // θh bins of the lobe sampler
  const MAX_SPHERES = 16;             // spheres of a progression (serve's limit too)
  const PREVIEW_MS = 6;               // budget of the first frame drawn after an edit: its side
                                      // follows the measured cost per pixel (64 to 256)
  const BANDS = 8;                    // a full frame is drawn in bands, one per animation frame,
                                      // so that an edit's first image waits for one band at most
  const G = {
    available: false, reason: '', ready: false, error: null,
    k: 0, components: 0, mode: 'point', frames: 0, target: POINT_FRAMES,
    material: null, coefficients: [], exposure: 0,
    light: SPHERE_LIGHT.slice(), frameMs: [], latencies: [], pendingInputs: [], draws: 0,
    fullLatencies: [], pendingFull: [],
    predicted: false, confirmed: 0, corrected: 0, smooth: false, pointFrames: POINT_FRAMES, envFrames: ENV_FRAMES,
    memoryBytes: 0, size: 512,
  };
  window.gantry = window.gantry || {};
  window.gantry.gpu = G;

  let gl = null, shade = null, show = null, accum = null, fbo = null, basisTex = null, accumTarget = null;
  let meshProg = null, depthProg = null, uvProg = null, gridProg = null;
  let envTex = null, envRowCdf = null, envColCdf = null, envInfo = null, layout = null;
  let dirty = true, floorValue = 1e-3;

  const VS = `#version 300 es
  in vec2 aPos; void main() { gl_Position = vec4(aPos, 0.0, 1.0); }`;

  // What every shading program shares: the basis lookup, the BRDF of the coefficients in gC
  // (uniform for a sphere, per point for a textured mesh), the probe and lobe samplers, and the
  // lighting of one surface point.
  const COMMON = `#version 300 es
  precision highp float; precision highp int; precision highp sampler3D; precision highp sampler2D;
  precision highp sampler2DArray; precision highp sampler2DShadow;
  float gC[${MAX_K}];
  uniform sampler2DArray uCoefTex; uniform int uVarying; uniform sampler2DShadow uShadow;
  uniform mat4 uLightViewProj; uniform int uShadowOn;
  uniform sampler3D uBasis; uniform ivec2 uLayout; uniform vec3 uTexSize; uniform vec3 uGrid;
  uniform int uK; uniform float uCoef[${MAX_K}]; uniform float uFloor;
  uniform int uMode; uniform vec3 uLight; uniform vec3 uIntensity;
  uniform vec2 uSize; uniform int uFrame;
  uniform sampler2D uEnv; uniform sampler2D uRowCdf; uniform sampler2D uColCdf;
  uniform ivec2 uEnvSize; uniform float uEnvTotal; uniform int uEnvSamples;
  uniform sampler2D uLobe; uniform int uPass; uniform int uSmooth;
  uniform int uSpheres; uniform vec3 uCentres[${MAX_SPHERES}];
  out vec4 outColor;
  const float PI = 3.14159265358979;
  uint hash(uint x) { x ^= x >> 16; x *= 0x7feb352du; x ^= x >> 15; x *= 0x846ca68bu; x ^= x >> 16; return x; }
  uint rngState;
  float rnd() { rngState = hash(rngState + 0x9e3779b9u); return float(rngState >> 8) * (1.0 / 16777216.0); }
  vec3 block(int b, vec3 p) {
    int slab = b / uLayout.y; int t = b - slab * uLayout.y;
    int ty = t / uLayout.x; int tx = t - ty * uLayout.x;
    vec3 c = vec3(float(tx) * uGrid.z + p.z + 0.5, float(ty) * uGrid.y + p.y + 0.5, float(slab) * uGrid.x + p.x + 0.5);
    return texture(uBasis, c / uTexSize).rgb;
  }
  // BRDF of the coefficients for a direction pair in the local frame (z = normal).
  vec3 brdf(vec3 wi, vec3 wo) {
    vec3 h = normalize(wi + wo);
    // atan, not acos: in single precision acos(h.z) cannot tell θh apart below about 3e-4 rad,
    // while the first θh bin of the table ends at 2e-4 rad (a mirror's peak).
    float thetaH = atan(length(h.xy), h.z);
    float phiH = length(h.xy) > 1e-9 ? atan(h.y, h.x) : 0.0;
    float cp = cos(phiH), sp = sin(phiH), ct = cos(thetaH), st = sin(thetaH);
    vec3 r = vec3(cp * wi.x + sp * wi.y, -sp * wi.x + cp * wi.y, wi.z);
    vec3 d = vec3(ct * r.x - st * r.z, r.y, st * r.x + ct * r.z);
    float thetaD = atan(length(d.xy), d.z);
    float phiD = length(d.xy) > 1e-9 ? atan(d.y, d.x) : 0.0;
    // Texel positions on the reduced grid (serve::GpuGrid::position): θd and φd interpolated
    // between bin centres (φd has period π); θh's bin taken whole as the table lookup does,
    // or interpolated too with "smooth highlights".
    vec3 q = vec3(sqrt(thetaH / (0.5 * PI)), thetaD / (0.5 * PI), mod(phiD, PI) / PI) * uGrid;
    vec3 p = clamp(q - 0.5, vec3(0.0), uGrid - 1.0);
    if (uSmooth == 0) p.x = clamp(floor(q.x), 0.0, uGrid.x - 1.0);
    vec3 y = block(0, p);
    for (int j = 0; j < ${MAX_K}; j++) { if (j >= uK) break; y += gC[j] * block(j + 1, p); }
    return max(exp(y) - uFloor, 0.0);
  }
  vec3 envDir(float u, float v) { float t = v * PI, f = u * 2.0 * PI; return vec3(sin(t) * sin(f), cos(t), -sin(t) * cos(f)); }
  ivec2 envPixel(vec3 d) {
    float t = atan(length(d.xz), d.y); float f = mod(atan(d.x, -d.z), 2.0 * PI);
    return clamp(ivec2(int(f / (2.0 * PI) * float(uEnvSize.x)), int(t / PI * float(uEnvSize.y))), ivec2(0), uEnvSize - 1);
  }
  vec3 envLookup(vec3 d) { return texelFetch(uEnv, envPixel(d), 0).rgb; }
  // Solid-angle density of the probe's sampling (luminance × sin θ per pixel, uniform inside).
  float envPdf(vec3 d, vec3 Le, int row) {
    float w = dot(Le, vec3(0.2126, 0.7152, 0.0722)) * sin((float(row) + 0.5) / float(uEnvSize.y) * PI);
    float sinT = length(d.xz);
    if (w <= 0.0 || sinT <= 1e-6) return 0.0;
    return w / uEnvTotal * float(uEnvSize.x * uEnvSize.y) / (2.0 * PI * PI * sinT);
  }
  // First index whose CDF value exceeds xi (row CDF: 1 × H texels; column CDFs: W × H).
  int searchRow(float xi) { int lo = 0, hi = uEnvSize.y - 1;
    while (lo < hi) { int m = (lo + hi) / 2; if (texelFetch(uRowCdf, ivec2(m, 0), 0).r > xi) hi = m; else lo = m + 1; } return lo; }
  int searchCol(int row, float xi) { int lo = 0, hi = uEnvSize.x - 1;
    while (lo < hi) { int m = (lo + hi) / 2; if (texelFetch(uColCdf, ivec2(m, row), 0).r > xi) hi = m; else lo = m + 1; } return lo; }
  // The material's lobe: half vectors drawn from its θh profile at θd = 0 (uLobe: per θh bin of
  // ${LOBE_BINS}, x = CDF, y = probability; row gLobeRow: a progression has one per sphere),
  // φh uniform, mirrored about h.
  int gLobeRow = 0;
  float thetaEdge(int i) { float s = float(i) / ${LOBE_BINS}.0; return s * s * 0.5 * PI; }
  float lobePdf(vec3 wi, vec3 wo) {
    vec3 h = normalize(wi + wo); float th = atan(length(h.xy), h.z);
    int i = clamp(int(sqrt(th / (0.5 * PI)) * ${LOBE_BINS}.0), 0, ${LOBE_BINS - 1});
    float sinH = sin(th), dot_ = dot(wo, h);
    if (sinH <= 1e-6 || dot_ <= 0.0) return 0.0;
    float p = texelFetch(uLobe, ivec2(i, gLobeRow), 0).y / (thetaEdge(i + 1) - thetaEdge(i));
    return p / (2.0 * PI * sinH) / (4.0 * dot_);
  }
  vec3 lobeSample(vec3 wo) {
    float xi = rnd(); int lo = 0, hi = ${LOBE_BINS - 1};
    while (lo < hi) { int m = (lo + hi) / 2; if (texelFetch(uLobe, ivec2(m, gLobeRow), 0).x > xi) hi = m; else lo = m + 1; }
    float th = mix(thetaEdge(lo), thetaEdge(lo + 1), rnd()), ph = 2.0 * PI * rnd();
    vec3 h = vec3(sin(th) * cos(ph), sin(th) * sin(ph), cos(th));
    return 2.0 * dot(wo, h) * h - wo;
  }
  vec3 toWorld(vec3 v, vec3 t, vec3 bt, vec3 n) { return v.x * t + v.y * bt + v.z * n; }
  void coefficientsAt(vec2 uv) {
    if (uVarying == 0) { for (int j = 0; j < ${MAX_K}; j++) { if (j >= uK) break; gC[j] = uCoef[j]; } return; }
    for (int j = 0; j < ${MAX_K}; j += 4) {
      if (j >= uK) break;
      vec4 c = texture(uCoefTex, vec3(uv, float(j / 4)));
      gC[j] = c.x; if (j + 1 < ${MAX_K}) gC[j + 1] = c.y; if (j + 2 < ${MAX_K}) gC[j + 2] = c.z; if (j + 3 < ${MAX_K}) gC[j + 3] = c.w;
    }
  }
  // The nearest of the uSpheres unit spheres at uCentres along o + t d, t in (0, tMax): its
  // index (-1 for none) and t.
  int nearestSphere(vec3 o, vec3 d, float tMax, out float tHit) {
    int found = -1; tHit = tMax;
    for (int i = 0; i < ${MAX_SPHERES}; i++) {
      if (i >= uSpheres) break;
      vec3 oc = o - uCentres[i];
      float b = dot(oc, d), c = dot(oc, oc) - 1.0, disc = b * b - c;
      if (disc < 0.0) continue;
      float t = -b - sqrt(disc);
      if (t > 1e-4 && t < tHit) { tHit = t; found = i; }
    }
    return found;
  }
  // 1 where nothing of the scene lies between pos and pos + tMax dir (only spheres of a
  // progression occlude: a single sphere cannot shade itself from a light above its horizon).
  float openTowards(vec3 pos, vec3 ng, vec3 dir, float tMax) {
    if (uSpheres == 0) return 1.0;
    float t; return nearestSphere(pos + 1e-3 * ng, dir, tMax, t) < 0 ? 1.0 : 0.0;
  }
  // 1 where the point light reaches pos (a shadow map for meshes, the spheres of a
  // progression, nothing for a single sphere).
  float lightVisible(vec3 pos, vec3 ng) {
    if (uSpheres > 0) { vec3 toL = uLight - pos; return openTowards(pos, ng, normalize(toL), length(toL)); }
    if (uShadowOn == 0) return 1.0;
    vec4 q = uLightViewProj * vec4(pos + 0.01 * ng, 1.0);
    vec3 p = q.xyz / q.w * 0.5 + 0.5;
    if (any(lessThan(p, vec3(0.0))) || any(greaterThan(p, vec3(1.0)))) return 1.0;
    return texture(uShadow, vec3(p.xy, p.z - 0.0005));
  }
  // Radiance towards woW from the point pos with shading normal n (geometric normal ng).
  vec3 shadePoint(vec3 pos, vec3 n, vec3 ng, vec3 woW) {
    vec3 a = abs(n.x) > 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
    vec3 t = normalize(cross(a, n)), bt = cross(n, t);
    vec3 wo = vec3(dot(woW, t), dot(woW, bt), dot(woW, n));
    vec3 L = vec3(0.0);
    if (wo.z <= 0.0) return L;
    if (uMode == 0) {
      vec3 toL = uLight - pos; float d2 = dot(toL, toL); vec3 wiW = toL / sqrt(d2);
      vec3 wi = vec3(dot(wiW, t), dot(wiW, bt), dot(wiW, n));
      if (wi.z > 0.0 && dot(wiW, ng) > 0.0) L = brdf(wi, wo) * uIntensity * wi.z / d2 * lightVisible(pos, ng);
      return L;
    }
    // One probe sample and one lobe sample per round, combined by the balance heuristic.
    for (int s = 0; s < 16; s++) {
      if (s >= uEnvSamples) break;
      int row = searchRow(rnd()); int col = searchCol(row, rnd());
      float u = (float(col) + rnd()) / float(uEnvSize.x), v = (float(row) + rnd()) / float(uEnvSize.y);
      vec3 wiW = envDir(u, v);
      vec3 wi = vec3(dot(wiW, t), dot(wiW, bt), dot(wiW, n));
      if (wi.z > 0.0) {
        vec3 Le = texelFetch(uEnv, ivec2(col, row), 0).rgb;
        float pe = envPdf(wiW, Le, row), pl = lobePdf(wi, wo);
        if (pe > 0.0) L += brdf(wi, wo) * Le * wi.z / (pe + pl) * openTowards(pos, ng, wiW, 1e30);
      }
      wi = lobeSample(wo);
      if (wi.z > 0.0) {
        wiW = toWorld(wi, t, bt, n);
        ivec2 px = envPixel(wiW);
        vec3 Le = texelFetch(uEnv, px, 0).rgb;
        float pe = envPdf(wiW, Le, px.y), pl = lobePdf(wi, wo);
        if (pl > 0.0) L += brdf(wi, wo) * Le * wi.z / (pe + pl) * openTowards(pos, ng, wiW, 1e30);
      }
    }
    return L / float(uEnvSamples);
  }
  `;

  // The sphere of render::sphere_scene, ray cast per pixel; pass 1 draws the lobe sampler's
  // θh profile instead.
  const FS = COMMON + `
  void main() {
    coefficientsAt(vec2(0.0));
    if (uPass == 1) {
      // θh profile of the material at θd = 0 for the lobe sampler: f · cos θh · sin θh · Δθh.
      int i = int(gl_FragCoord.x);
      float th = 0.5 * (thetaEdge(i) + thetaEdge(i + 1));
      vec3 h = vec3(sin(th), 0.0, cos(th));
      float f = dot(brdf(h, h), vec3(0.2126, 0.7152, 0.0722));
      outColor = vec4(f * cos(th) * sin(th) * (thetaEdge(i + 1) - thetaEdge(i)), 0.0, 0.0, 1.0);
      return;
    }
    vec2 pix = vec2(gl_FragCoord.x, uSize.y - gl_FragCoord.y);
    rngState = hash(uint(pix.x) + 4096u * uint(pix.y)) ^ hash(uint(uFrame) * 7919u + 1u);
    vec2 jit = uFrame < 0 ? vec2(0.0) : vec2(rnd(), rnd()) - 0.5;
    vec2 xy = floor(pix) + 0.5 + jit;
    // render::sphere_scene's camera: at (0, 0, 4) looking at the origin, 32° vertical field.
    float hfov = tan(radians(16.0)), aspect = uSize.x / uSize.y;
    vec3 dir = normalize(vec3((2.0 * xy.x / uSize.x - 1.0) * hfov * aspect, (1.0 - 2.0 * xy.y / uSize.y) * hfov, -1.0));
    vec3 o = vec3(0.0, 0.0, 4.0);
    float b = dot(o, dir), c = dot(o, o) - 1.0, disc = b * b - c;
    if (disc < 0.0) { outColor = vec4(uMode == 1 ? envLookup(dir) : vec3(0.0), 1.0); return; }
    vec3 pos = o + (-b - sqrt(disc)) * dir;
    vec3 n = normalize(pos);
    outColor = vec4(shadePoint(pos, n, n, -dir), 1.0);
  }`;

  // A progression of spheres (thesis fig. 5-7; render::SphereGrid): ray cast from the grid's
  // camera (on +z looking down -z, vertical half-angle tangent uTanHalf); sphere i reads its
  // coefficients from texel i of a one-row coefficient texture.
  const FS_GRID = COMMON + `
  uniform vec3 uCamPos; uniform float uTanHalf;
  void main() {
    vec2 pix = vec2(gl_FragCoord.x, uSize.y - gl_FragCoord.y);
    rngState = hash(uint(pix.x) + 4096u * uint(pix.y)) ^ hash(uint(uFrame) * 7919u + 1u);
    vec2 jit = uFrame < 0 ? vec2(0.0) : vec2(rnd(), rnd()) - 0.5;
    vec2 xy = floor(pix) + 0.5 + jit;
    float aspect = uSize.x / uSize.y;
    vec3 dir = normalize(vec3((2.0 * xy.x / uSize.x - 1.0) * uTanHalf * aspect, (1.0 - 2.0 * xy.y / uSize.y) * uTanHalf, -1.0));
    float t; int i = nearestSphere(uCamPos, dir, 1e30, t);
    if (i < 0) { outColor = vec4(uMode == 1 ? envLookup(dir) : vec3(0.0), 1.0); return; }
    coefficientsAt(vec2((float(i) + 0.5) / float(uSpheres), 0.5));
    gLobeRow = i;
    vec3 pos = uCamPos + t * dir;
    vec3 n = normalize(pos - uCentres[i]);
    outColor = vec4(shadePoint(pos, n, n, -dir), 1.0);
  }`;

  // A textured mesh (the figure's teapot), rasterized with render::teapot_camera; each point
  // reads its coefficients from the coefficient texture at its uv.
  const VS_MESH = `#version 300 es
  in vec3 aPos; in vec3 aNormal; in vec2 aUv;
  uniform mat4 uViewProj; uniform vec2 uJitterClip;
  out vec3 vPos; out vec3 vNormal; out vec2 vUv;
  void main() {
    vPos = aPos; vNormal = aNormal; vUv = aUv;
    vec4 p = uViewProj * vec4(aPos, 1.0);
    p.xy += uJitterClip * p.w;
    gl_Position = p;
  }`;
  const FS_MESH = COMMON + `
  in vec3 vPos; in vec3 vNormal; in vec2 vUv;
  uniform vec3 uCamPos;
  void main() {
    rngState = hash(uint(gl_FragCoord.x) + 4096u * uint(gl_FragCoord.y)) ^ hash(uint(uFrame) * 7919u + 1u);
    coefficientsAt(vUv);
    vec3 ng = normalize(cross(dFdx(vPos), dFdy(vPos)));
    vec3 woW = normalize(uCamPos - vPos);
    if (dot(ng, woW) < 0.0) ng = -ng;
    vec3 n = normalize(vNormal);
    if (dot(n, ng) < 0.0) n = -n;
    outColor = vec4(shadePoint(vPos, n, ng, woW), 1.0);
  }`;
  // Depth from the point light, for the shadow map; and the uv under each pixel, for the brush.
  const VS_DEPTH = `#version 300 es
  in vec3 aPos; uniform mat4 uViewProj; void main() { gl_Position = uViewProj * vec4(aPos, 1.0); }`;
  const FS_DEPTH = `#version 300 es
  precision highp float; out vec4 outColor; void main() { outColor = vec4(1.0); }`;
  const FS_UV = `#version 300 es
  precision highp float; in vec3 vPos; in vec3 vNormal; in vec2 vUv; out vec4 outColor;
  void main() { outColor = vec4(vUv, 1.0, 1.0); }`;

  const FS_SHOW = `#version 300 es
  precision highp float; uniform sampler2D uAccum; uniform float uScale; uniform float uRatio; out vec4 outColor;
  float srgb(float x) { x = clamp(x, 0.0, 1.0); return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055; }
  void main() { vec3 v = texelFetch(uAccum, ivec2(gl_FragCoord.xy * uRatio), 0).rgb * uScale;
    outColor = vec4(srgb(v.r), srgb(v.g), srgb(v.b), 1.0); }`;

  function compile(vs, fs) {
    const p = gl.createProgram();
    for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
      const s = gl.createShader(type);
      gl.shaderSource(s, src); gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error('shader: ' + gl.getShaderInfoLog(s));
      gl.attachShader(p, s);
    }
    gl.bindAttribLocation(p, 0, 'aPos'); gl.bindAttribLocation(p, 1, 'aNormal'); gl.bindAttribLocation(p, 2, 'aUv');
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error('program: ' + gl.getProgramInfoLog(p));
    const u = {};
    const n = gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS);
    for (let i = 0; i < n; i++) { const name = gl.getActiveUniform(p, i).name.replace(/\[0\]$/, ''); u[name] = gl.getUniformLocation(p, name); }
    return { p, u };
  }

  function setStatus(text) { const e = $('gpu-status'); if (e) e.textContent = text; }

  function init() {
    const canvas = $('gpu-canvas');
    if (!canvas) return false;
    gl = canvas.getContext('webgl2', { antialias: false, preserveDrawingBuffer: true });
    if (!gl) { G.reason = 'WebGL2 is not available in this browser'; return false; }
    if (!gl.getExtension('EXT_color_buffer_float')) { G.reason = 'this browser cannot render to float textures (EXT_color_buffer_float)'; return false; }
    G.floatBlend = !!gl.getExtension('EXT_float_blend');
    if (!G.floatBlend) { G.reason = 'this browser cannot blend float textures (EXT_float_blend)'; return false; }
    shade = compile(VS, FS); show = compile(VS, FS_SHOW);
    meshProg = compile(VS_MESH, FS_MESH); depthProg = compile(VS_DEPTH, FS_DEPTH); uvProg = compile(VS_MESH, FS_UV);
    gridProg = compile(VS, FS_GRID);
    const vb = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, vb);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
    G.floatLinear = !!gl.getExtension('OES_texture_float_linear');
    if (!resize(canvas.width, canvas.height)) { G.reason = 'float framebuffer incomplete'; return false; }
    G.glError = () => gl.getError();
    return true;
  }

  // A colour target (RGBA32F) with a depth buffer, for accumulating frames and for previews.
  function target(w, h) {
    const tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, w, h);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    const depth = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, depth);
    gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT24, w, h);
    const f = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, f);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tex, 0);
    gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, depth);
    const ok = gl.checkFramebufferStatus(gl.FRAMEBUFFER) === gl.FRAMEBUFFER_COMPLETE;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    return ok ? { tex, depth, fbo: f, w, h } : null;
  }
  function drop(t) { if (t) { gl.deleteTexture(t.tex); gl.deleteRenderbuffer(t.depth); gl.deleteFramebuffer(t.fbo); } }

  // Sizes the canvas and the accumulation target (the sphere is square, the teapot 4:3).
  function resize(w, h) {
    const canvas = $('gpu-canvas');
    if (accumTarget && accumTarget.w === w && accumTarget.h === h) return true;
    drop(accumTarget);
    accumTarget = target(w, h);
    if (!accumTarget) return false;
    accum = accumTarget.tex; fbo = accumTarget.fbo;
    canvas.width = w; canvas.height = h;
    canvas.style.height = `${Math.round(320 * h / w)}px`;
    G.width = w; G.height = h; G.size = w;
    dirty = true;
    return true;
  }

  async function fetchBytes(url) {
    const r = await fetch(url);
    if (!r.ok) { let m = `${r.status}`; try { m = (await r.json()).error || m; } catch (_) { /* binary */ } throw new Error(m); }
    return new DataView(await r.arrayBuffer());
  }

  async function loadBasis() {
    const dv = await fetchBytes('/api/gpu/basis.bin');
    const magic = String.fromCharCode(dv.getUint8(0), dv.getUint8(1), dv.getUint8(2), dv.getUint8(3));
    const [version, th, td, pd, k] = [4, 8, 12, 16, 20].map((o) => dv.getUint32(o, true));
    if (magic !== 'GPUB' || version !== 1 || !(th > 0 && td > 0 && pd > 0)) throw new Error('unexpected basis file');
    [TH, TD, PD] = [th, td, pd];
    floorValue = dv.getFloat32(24, true);
    const blocks = k + 1, per = TH * TD * PD * 3;
    const halves = new Uint16Array(dv.buffer, dv.byteOffset + 28, blocks * per);
    // Blocks tiled over x (φd) and y (θd), then stacked in slabs along z (θh), keeping each
    // side within 256 texels where the grid allows (WebGL2's guaranteed 3-D size).
    const cols = Math.max(1, Math.min(blocks, Math.floor(256 / PD)));
    const rows = Math.max(1, Math.min(Math.ceil(blocks / cols), Math.floor(256 / TD)));
    const perSlab = cols * rows;
    const slabs = Math.ceil(blocks / perSlab);
    const size = [PD * cols, TD * rows, TH * slabs];
    const max3d = gl.getParameter(gl.MAX_3D_TEXTURE_SIZE);
    if (size.some((s) => s > max3d)) throw new Error(`the basis needs a ${size.join('×')} 3-D texture, this GPU allows ${max3d}`);
    basisTex = gl.createTexture();
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_3D, basisTex);
    gl.texStorage3D(gl.TEXTURE_3D, 1, gl.RGB16F, size[0], size[1], size[2]);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    for (let b = 0; b < blocks; b++) {
      const slab = Math.floor(b / perSlab), t = b % perSlab;
      gl.texSubImage3D(gl.TEXTURE_3D, 0, (t % cols) * PD, Math.floor(t / cols) * TD, slab * TH, PD, TD, TH,
        gl.RGB, gl.HALF_FLOAT, halves.subarray(b * per, (b + 1) * per));
    }
    for (const [p, v] of [[gl.TEXTURE_MIN_FILTER, gl.LINEAR], [gl.TEXTURE_MAG_FILTER, gl.LINEAR],
      [gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE], [gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE], [gl.TEXTURE_WRAP_R, gl.CLAMP_TO_EDGE]]) gl.texParameteri(gl.TEXTURE_3D, p, v);
    layout = { cols, perSlab, size };
    G.components = Math.min(k, MAX_K);
    G.memoryBytes = blocks * per * 2;
    const kIn = $('gpu-k');
    kIn.max = String(G.components); kIn.value = String(G.components); G.k = G.components;
    $('gpu-k-out').textContent = `k = ${G.k}`;
  }

  // The probe: the server's (/api/gpu/environment.bin) or one given as GPUE bytes.
  async function loadEnvironment(given) {
    const dv = given || await fetchBytes('/api/gpu/environment.bin');
    const magic = String.fromCharCode(dv.getUint8(0), dv.getUint8(1), dv.getUint8(2), dv.getUint8(3));
    const w = dv.getUint32(4, true), h = dv.getUint32(8, true);
    if (magic !== 'GPUE' || !(w > 0 && h > 0) || dv.byteLength < 12 + 6 * w * h) throw new Error('unexpected probe file');
    for (const t of [envTex, envRowCdf, envColCdf]) if (t) gl.deleteTexture(t);
    const halves = new Uint16Array(dv.buffer, dv.byteOffset + 12, w * h * 3);
    const half = (x) => { const s = x >> 15 ? -1 : 1, e = (x >> 10) & 31, m = x & 1023;
      return e === 0 ? s * m * 2 ** -24 : e === 31 ? 0 : s * (1 + m / 1024) * 2 ** (e - 15); };
    // Sampling tables: luminance × sin θ per pixel; per-row column CDFs and the row CDF.
    const colCdf = new Float32Array(w * h), rowCdf = new Float32Array(h);
    let total = 0;
    for (let y = 0; y < h; y++) {
      const s = Math.sin(((y + 0.5) / h) * Math.PI);
      let row = 0;
      for (let x = 0; x < w; x++) {
        const i = (y * w + x) * 3;
        const lum = 0.2126 * half(halves[i]) + 0.7152 * half(halves[i + 1]) + 0.0722 * half(halves[i + 2]);
        row += Math.max(0, lum) * s; colCdf[y * w + x] = row;
      }
      for (let x = 0; x < w; x++) colCdf[y * w + x] = row > 0 ? colCdf[y * w + x] / row : (x + 1) / w;
      total += row; rowCdf[y] = total;
    }
    for (let y = 0; y < h; y++) rowCdf[y] = total > 0 ? rowCdf[y] / total : (y + 1) / h;
    const tex = (unit, internal, format, type, width, height, data) => {
      const t = gl.createTexture();
      gl.activeTexture(gl.TEXTURE0 + unit); gl.bindTexture(gl.TEXTURE_2D, t);
      gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
      gl.texImage2D(gl.TEXTURE_2D, 0, internal, width, height, 0, format, type, data);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      return t;
    };
    envTex = tex(1, gl.RGB16F, gl.RGB, gl.HALF_FLOAT, w, h, halves);
    envRowCdf = tex(2, gl.R32F, gl.RED, gl.FLOAT, h, 1, rowCdf);
    envColCdf = tex(3, gl.R32F, gl.RED, gl.FLOAT, w, h, colCdf);
    gl.activeTexture(gl.TEXTURE0);
    // Σ (luminance × sin θ) over pixels, with the same per-pixel weights the shader recomputes.
    envInfo = { w, h, total };
    dirty = true;
  }

  // A probe chosen in the page: the server decodes it (OpenEXR or Radiance .hdr) and sends it
  // back in half floats; nothing is kept there.
  async function uploadProbe(file) {
    setStatus(`reading ${file.name}…`);
    const r = await fetch('/api/gpu/environment', { method: 'POST', body: file });
    if (!r.ok) { let m = `${r.status}`; try { m = (await r.json()).error || m; } catch (_) { /* not JSON */ } throw new Error(m); }
    await loadEnvironment(new DataView(await r.arrayBuffer()));
    G.probe = file.name;
    G.mode = 'env'; $('gpu-mode').value = 'env';
    setStatus(`light probe: ${file.name} (${envInfo.w}×${envInfo.h})`);
  }
  G.uploadProbe = uploadProbe;

  function bindAll() {
    gl.activeTexture(gl.TEXTURE0); gl.bindTexture(gl.TEXTURE_3D, basisTex);
    if (envTex) {
      gl.activeTexture(gl.TEXTURE1); gl.bindTexture(gl.TEXTURE_2D, envTex);
      gl.activeTexture(gl.TEXTURE2); gl.bindTexture(gl.TEXTURE_2D, envRowCdf);
      gl.activeTexture(gl.TEXTURE3); gl.bindTexture(gl.TEXTURE_2D, envColCdf);
    }
    gl.activeTexture(gl.TEXTURE4); gl.bindTexture(gl.TEXTURE_2D, accum);
    if (lobeTex) { gl.activeTexture(gl.TEXTURE5); gl.bindTexture(gl.TEXTURE_2D, lobeTex); }
    const coefTex = G.scene === 'grid' ? GR.coefTex : T.coefTex;
    if (coefTex) { gl.activeTexture(gl.TEXTURE6); gl.bindTexture(gl.TEXTURE_2D_ARRAY, coefTex); }
    if (T.shadow) { gl.activeTexture(gl.TEXTURE7); gl.bindTexture(gl.TEXTURE_2D, T.shadow); }
    gl.activeTexture(gl.TEXTURE0);
  }

  function setUniforms(u) {
    gl.uniform1i(u.uBasis, 0); gl.uniform1i(u.uEnv, 1); gl.uniform1i(u.uRowCdf, 2); gl.uniform1i(u.uColCdf, 3);
    gl.uniform1i(u.uLobe, 5);
    gl.uniform2i(u.uLayout, layout.cols, layout.perSlab);
    gl.uniform3f(u.uTexSize, ...layout.size);
    gl.uniform3f(u.uGrid, TH, TD, PD);
    const c = new Float32Array(MAX_K);
    const k = Math.min(G.k, G.coefficients.length);
    for (let j = 0; j < k; j++) c[j] = G.coefficients[j];
    gl.uniform1i(u.uK, k); gl.uniform1fv(u.uCoef, c); gl.uniform1f(u.uFloor, floorValue);
    gl.uniform1i(u.uMode, G.mode === 'env' ? 1 : 0);
    gl.uniform3f(u.uLight, ...G.light);
    // render::sphere_scene's intensity: π d² with d the light's distance to the sphere's top.
    const d = Math.hypot(...G.light) - 1;
    gl.uniform3f(u.uIntensity, Math.PI * d * d, Math.PI * d * d, Math.PI * d * d);
    gl.uniform2f(u.uSize, G.width, G.height); gl.uniform1i(u.uFrame, G.frames);
    gl.uniform1i(u.uCoefTex, 6); gl.uniform1i(u.uShadow, 7); gl.uniform1i(u.uVarying, 0); gl.uniform1i(u.uShadowOn, 0);
    gl.uniform1i(u.uSpheres, 0);
    if (envInfo) { gl.uniform2i(u.uEnvSize, envInfo.w, envInfo.h); gl.uniform1f(u.uEnvTotal, envInfo.total); }
    gl.uniform1i(u.uEnvSamples, ENV_SAMPLES);
    gl.uniform1i(u.uSmooth, G.smooth ? 1 : 0);
  }

  // The lobe sampler's tables: the θh profile of each material drawn on the GPU (LOBE_BINS
  // texels, one row per material: the shown material, or each sphere of a progression), read
  // back, turned into CDFs.
  let lobeTarget = null, lobeFbo = null, lobeTex = null, lobeKey = '';
  function lobeMaterials() {
    if (G.scene === 'grid' && GR.nodes) {
      const k = Math.min(G.k, ...GR.nodes.map((n) => n.length));
      return Array.from({ length: GR.count }, (_, i) => Array.from(pathAt(GR.nodes, i / (GR.count - 1), k)));
    }
    return [G.coefficients.slice(0, Math.min(G.k, G.coefficients.length))];
  }
  function updateLobe() {
    const rows = lobeMaterials();
    const key = JSON.stringify(rows);
    if (key === lobeKey) return;
    lobeKey = key;
    if (!lobeTarget) {
      lobeTarget = gl.createTexture(); gl.bindTexture(gl.TEXTURE_2D, lobeTarget);
      gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, LOBE_BINS, MAX_SPHERES);
      lobeFbo = gl.createFramebuffer(); gl.bindFramebuffer(gl.FRAMEBUFFER, lobeFbo);
      gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, lobeTarget, 0);
      lobeTex = gl.createTexture(); gl.activeTexture(gl.TEXTURE5); gl.bindTexture(gl.TEXTURE_2D, lobeTex);
      gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RG32F, LOBE_BINS, MAX_SPHERES);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      gl.activeTexture(gl.TEXTURE0);
    }
    bindAll();
    gl.bindFramebuffer(gl.FRAMEBUFFER, lobeFbo);
    gl.useProgram(shade.p);
    setUniforms(shade.u);
    gl.uniform1i(shade.u.uPass, 1);
    rows.forEach((c, r) => {
      const coef = new Float32Array(MAX_K); coef.set(c.slice(0, MAX_K));
      gl.uniform1i(shade.u.uK, Math.min(c.length, MAX_K)); gl.uniform1fv(shade.u.uCoef, coef);
      gl.viewport(0, r, LOBE_BINS, 1);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
    });
    const px = new Float32Array(LOBE_BINS * rows.length * 4);
    gl.readPixels(0, 0, LOBE_BINS, rows.length, gl.RGBA, gl.FLOAT, px);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    const table = new Float32Array(LOBE_BINS * rows.length * 2);
    for (let r = 0; r < rows.length; r++) {
      const v = (i) => Math.max(0, px[(r * LOBE_BINS + i) * 4]) || 0;
      let total = 0;
      for (let i = 0; i < LOBE_BINS; i++) total += v(i);
      let run = 0;
      for (let i = 0; i < LOBE_BINS; i++) {
        const p = total > 0 ? v(i) / total : 1 / LOBE_BINS, o = 2 * (r * LOBE_BINS + i);
        run += p; table[o] = i === LOBE_BINS - 1 ? 1 : run; table[o + 1] = p;
      }
    }
    gl.activeTexture(gl.TEXTURE5); gl.bindTexture(gl.TEXTURE_2D, lobeTex);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, LOBE_BINS, rows.length, gl.RG, gl.FLOAT, table);
    gl.activeTexture(gl.TEXTURE0);
  }

  // One frame: one sample per pixel (ENV_SAMPLES rounds under the probe) added into the float
  // target, then the average shown. With `preview`, a single frame at previewSide()² into its own
  // target, shown enlarged: the first image after an edit, while the full one accumulates.
  let previewTarget = null;
  function previewSide() {
    const ms = G.msPerPixel > 0 ? G.msPerPixel : 100 / (512 * 512);
    return Math.max(64, Math.min(256, 16 * Math.floor(Math.sqrt(PREVIEW_MS / ms) / 16)));
  }
  function frame(preview, band = -1) {
    const side = preview ? previewSide() : 0;
    const W = preview ? side : G.width;
    const H = preview ? Math.round((side * G.height) / G.width) : G.height;
    if (preview) G.previewSide = W;
    const last = band < 0 || band === BANDS - 1;
    if (G.mode === 'env') updateLobe();
    if (preview && !previewTarget) previewTarget = target(256, 256);
    bindAll();
    gl.bindFramebuffer(gl.FRAMEBUFFER, preview ? previewTarget.fbo : fbo);
    gl.viewport(0, 0, W, H);
    // The whole target is cleared before the first band of the first frame (a scissor would
    // keep the other bands' old sums).
    if (preview || (G.frames === 0 && band <= 0)) { gl.clearColor(0, 0, 0, 0); gl.clear(gl.COLOR_BUFFER_BIT); }
    if (band >= 0) {
      const rows = Math.ceil(H / BANDS);
      gl.enable(gl.SCISSOR_TEST); gl.scissor(0, band * rows, W, rows);
    }
    // Accumulated frames sample the pixel at random (a fixed first sample at its centre would
    // bias a mirror's few highlight pixels); a preview (index −1) looks through the centre.
    const index = preview ? -1 : G.frames;
    if (MESHES.includes(G.scene)) drawTeapot(W, H, index);
    else if (G.scene === 'grid') drawGrid(W, H, index);
    else {
      gl.useProgram(shade.p);
      setUniforms(shade.u);
      gl.uniform2f(shade.u.uSize, W, H);
      gl.uniform1i(shade.u.uFrame, index);
      gl.uniform1i(shade.u.uPass, 0);
      gl.enable(gl.BLEND); gl.blendFunc(gl.ONE, gl.ONE);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
      gl.disable(gl.BLEND);
    }
    gl.disable(gl.SCISSOR_TEST);
    if (!last) { gl.bindFramebuffer(gl.FRAMEBUFFER, null); return; }
    if (!preview) G.frames++;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, G.width, G.height);
    gl.useProgram(show.p);
    if (preview) { gl.activeTexture(gl.TEXTURE4); gl.bindTexture(gl.TEXTURE_2D, previewTarget.tex); gl.activeTexture(gl.TEXTURE0); }
    gl.uniform1i(show.u.uAccum, 4);
    gl.uniform1f(show.u.uRatio, W / G.width);
    gl.uniform1f(show.u.uScale, 2 ** G.exposure / (preview ? 1 : G.frames));
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    G.draws++;
  }

  // ---------- spatially varying meshes: the rust teapot (thesis fig. 5-8) and bunny ----------
  // T holds the shown mesh's geometry (copied from its entry in T.cache) and the texture
  // shared by the meshes: the rust field, the painted trait edits, the process path's ends.
  const MESHES = ['teapot', 'bunny'];
  const T = { mesh: null, vao: null, count: 0, shadow: null, coefTex: null, uv: null, field: null,
    tw: 256, th: 128, nodes: null, offsets: {}, from: null, to: null, dirtyTexture: true, cache: {} };
  G.teapot = T;

  function lookAt(eye, at, up) {
    const f = norm(sub(at, eye)), r = norm(cross(f, up)), u = cross(r, f);
    return [r[0], u[0], -f[0], 0, r[1], u[1], -f[1], 0, r[2], u[2], -f[2], 0,
      -dot(r, eye), -dot(u, eye), dot(f, eye), 1];
  }
  function perspective(fovDeg, aspect, near, far) {
    const t = 1 / Math.tan((fovDeg * Math.PI) / 360);
    return [t / aspect, 0, 0, 0, 0, t, 0, 0, 0, 0, (far + near) / (near - far), -1, 0, 0, (2 * far * near) / (near - far), 0];
  }
  function mul(a, b) { // column-major 4 × 4: a · b
    const o = new Array(16).fill(0);
    for (let c = 0; c < 4; c++) for (let r = 0; r < 4; r++) for (let k = 0; k < 4; k++) o[c * 4 + r] += a[k * 4 + r] * b[c * 4 + k];
    return new Float32Array(o);
  }
  const sub = (a, b) => a.map((v, i) => v - b[i]);
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const norm = (a) => { const l = Math.hypot(...a); return a.map((v) => v / l); };

  // A mesh of the figures (serve's /api/gpu/meshes/NAME): its buffers, camera, light and
  // shadow map.
  async function loadMesh(name) {
    const dv = await fetchBytes(`/api/gpu/meshes/${name}`);
    const T = { name, uv: null };
    const n = dv.getUint32(8, true), t = dv.getUint32(12, true);
    const f = (o, len) => Array.from(new Float32Array(dv.buffer.slice(dv.byteOffset + o, dv.byteOffset + o + 4 * len)));
    const head = f(16, 16);
    T.camera = { position: head.slice(0, 3), lookAt: head.slice(3, 6), up: head.slice(6, 9), fov: head[9] };
    T.light = { position: head.slice(10, 13), intensity: head.slice(13, 16) };
    let o = 16 + 64;
    const arrays = [3 * n, 3 * n, 2 * n].map((len) => { const a = new Float32Array(dv.buffer.slice(dv.byteOffset + o, dv.byteOffset + o + 4 * len)); o += 4 * len; return a; });
    const idx = new Uint32Array(dv.buffer.slice(dv.byteOffset + o, dv.byteOffset + o + 12 * t));
    T.vao = gl.createVertexArray();
    gl.bindVertexArray(T.vao);
    arrays.forEach((a, loc) => {
      const b = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, b); gl.bufferData(gl.ARRAY_BUFFER, a, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(loc); gl.vertexAttribPointer(loc, loc === 2 ? 2 : 3, gl.FLOAT, false, 0, 0);
    });
    const ib = gl.createBuffer(); gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ib); gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, idx, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    T.count = 3 * t;
    const c = T.camera;
    T.viewProj = mul(perspective(c.fov, 4 / 3, 0.1, 50), lookAt(c.position, c.lookAt, c.up));
    T.lightViewProj = mul(perspective(30, 1, 1, 40), lookAt(T.light.position, c.lookAt, [0, 1, 0]));
    // The shadow map: depth seen from the light.
    const size = 2048;
    T.shadow = gl.createTexture();
    gl.activeTexture(gl.TEXTURE7); gl.bindTexture(gl.TEXTURE_2D, T.shadow);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.DEPTH_COMPONENT24, size, size);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_COMPARE_MODE, gl.COMPARE_REF_TO_TEXTURE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_COMPARE_FUNC, gl.LEQUAL);
    gl.activeTexture(gl.TEXTURE0);
    const sf = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, sf);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.TEXTURE_2D, T.shadow, 0);
    gl.viewport(0, 0, size, size);
    gl.clear(gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST); gl.colorMask(false, false, false, false);
    gl.useProgram(depthProg.p);
    gl.uniformMatrix4fv(depthProg.u.uViewProj, false, T.lightViewProj);
    gl.bindVertexArray(T.vao); gl.drawElements(gl.TRIANGLES, T.count, gl.UNSIGNED_INT, 0); gl.bindVertexArray(null);
    gl.colorMask(true, true, true, true); gl.disable(gl.DEPTH_TEST);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.deleteFramebuffer(sf);
    return T;
  }
  // The rust field, shared by the meshes.
  async function loadRustField() {
    const rv = await fetchBytes(`/api/gpu/rust.bin?width=${T.tw}&seed=1`);
    T.field = new Float32Array(rv.buffer.slice(rv.byteOffset + 12, rv.byteOffset + 12 + 4 * T.tw * T.th));
  }

  // The uv under each pixel of the teapot view (the brush's lookup), drawn once: the camera
  // does not move.
  function pickUv() {
    const t = target(G.width, G.height);
    gl.bindFramebuffer(gl.FRAMEBUFFER, t.fbo);
    gl.viewport(0, 0, G.width, G.height);
    gl.clearColor(0, 0, 0, 0); gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    gl.useProgram(uvProg.p);
    gl.uniformMatrix4fv(uvProg.u.uViewProj, false, T.viewProj);
    gl.uniform2f(uvProg.u.uJitterClip, 0, 0);
    gl.bindVertexArray(T.vao); gl.drawElements(gl.TRIANGLES, T.count, gl.UNSIGNED_INT, 0); gl.bindVertexArray(null);
    gl.disable(gl.DEPTH_TEST);
    T.uv = new Float32Array(G.width * G.height * 4);
    gl.readPixels(0, 0, G.width, G.height, gl.RGBA, gl.FLOAT, T.uv);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    drop(t);
  }

  // Each texel's coefficients: the process path at the texel's rust amount, plus the painted
  // trait edits (amount × the trait's unit step).
  function buildCoefficientTexture() {
    const k = Math.min(G.k, T.nodes[0].length), layers = Math.ceil(k / 4);
    const [a, b] = T.nodes;
    const data = new Float32Array(layers * T.th * T.tw * 4);
    const traits = Object.entries(T.offsets);
    for (let y = 0; y < T.th; y++) for (let x = 0; x < T.tw; x++) {
      const i = y * T.tw + x, t = T.field[i];
      for (let j = 0; j < k; j++) {
        let v = a[j] + t * (b[j] - a[j]);
        for (const [name, off] of traits) v += off[i] * (T.steps[name][j] || 0);
        data[((Math.floor(j / 4) * T.th + y) * T.tw + x) * 4 + (j % 4)] = v;
      }
    }
    if (T.coefTex) gl.deleteTexture(T.coefTex);
    T.coefTex = gl.createTexture();
    gl.activeTexture(gl.TEXTURE6); gl.bindTexture(gl.TEXTURE_2D_ARRAY, T.coefTex);
    gl.texImage3D(gl.TEXTURE_2D_ARRAY, 0, gl.RGBA32F, T.tw, T.th, layers, 0, gl.RGBA, gl.FLOAT, data);
    const filter = G.floatLinear ? gl.LINEAR : gl.NEAREST;
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, filter);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, filter);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_S, gl.REPEAT);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    gl.activeTexture(gl.TEXTURE0);
    T.builtK = k; T.dirtyTexture = false;
  }

  // Halton (2, 3) sub-pixel offsets of the jittered frames.
  function halton(i, base) { let f = 1, r = 0; while (i > 0) { f /= base; r += f * (i % base); i = Math.floor(i / base); } return r; }

  function drawTeapot(W, H, index) {
    if (T.dirtyTexture || T.builtK !== Math.min(G.k, T.nodes[0].length)) buildCoefficientTexture();
    const u = meshProg.u;
    gl.useProgram(meshProg.p);
    setUniforms(u);
    gl.uniform2f(u.uSize, W, H); gl.uniform1i(u.uFrame, index);
    gl.uniform1i(u.uK, T.builtK); gl.uniform1i(u.uVarying, 1);
    gl.uniform1i(u.uShadowOn, G.mode === 'env' ? 0 : 1);
    gl.uniformMatrix4fv(u.uViewProj, false, T.viewProj);
    gl.uniformMatrix4fv(u.uLightViewProj, false, T.lightViewProj);
    gl.uniform3f(u.uCamPos, ...T.camera.position);
    gl.uniform3f(u.uLight, ...T.light.position);
    gl.uniform3f(u.uIntensity, ...T.light.intensity);
    const j = index < 0 ? [0, 0] : [halton(index + 1, 2) - 0.5, halton(index + 1, 3) - 0.5];
    gl.uniform2f(u.uJitterClip, (2 * j[0]) / W, (-2 * j[1]) / H);
    // Depth first, then the shading of the nearest surface only, added to the frames so far.
    gl.enable(gl.DEPTH_TEST); gl.depthFunc(gl.LESS); gl.clear(gl.DEPTH_BUFFER_BIT);
    gl.bindVertexArray(T.vao);
    gl.colorMask(false, false, false, false);
    gl.drawElements(gl.TRIANGLES, T.count, gl.UNSIGNED_INT, 0);
    gl.colorMask(true, true, true, true);
    gl.depthFunc(gl.EQUAL);
    gl.enable(gl.BLEND); gl.blendFunc(gl.ONE, gl.ONE);
    gl.drawElements(gl.TRIANGLES, T.count, gl.UNSIGNED_INT, 0);
    gl.disable(gl.BLEND); gl.depthFunc(gl.LESS); gl.disable(gl.DEPTH_TEST);
    gl.bindVertexArray(null);
  }

  // Shows a scene: the sphere; a mesh (teapot, bunny) rusting from `from` (rust amount 0) to
  // `to` (1); or the progression ('grid') along the path through the materials `from`.
  async function setScene(scene, from, to) {
    if (scene === 'grid') return setGrid(from);
    $('gpu-teapot-controls').hidden = !MESHES.includes(scene);
    $('gpu-grid-controls').hidden = true;
    if (!MESHES.includes(scene)) { G.scene = scene; $('gpu-scene').value = scene; resize(512, 512); dirty = true; return; }
    // Everything loaded first: the view keeps drawing the old scene meanwhile.
    if (!T.cache[scene]) T.cache[scene] = await loadMesh(scene);
    if (!T.field) await loadRustField();
    from = from || $('gpu-from').value; to = to || $('gpu-to').value;
    const nodes = [await projection(from), await projection(to)];
    G.scene = scene;
    $('gpu-scene').value = scene; $('gpu-from').value = from; $('gpu-to').value = to;
    resize(512, 384);
    Object.assign(T, T.cache[scene]);
    if (!T.uv) { pickUv(); T.cache[scene].uv = T.uv; }
    T.nodes = nodes;
    T.from = from; T.to = to; T.dirtyTexture = true;
    dirty = true;
  }
  async function projection(name) {
    const r = await fetch(`/api/gpu/materials/${encodeURIComponent(name)}/coefficients`);
    if (!r.ok) throw new Error(`cannot project ${name}: ${(await r.json()).error || r.status}`);
    return (await r.json()).coefficients;
  }
  G.setScene = setScene;

  // ---------- the progression of a process (thesis fig. 5-7) ----------
  const GR = { count: 8, columns: 4, info: null, names: null, nodes: null, coefTex: null, builtK: 0 };
  G.grid = GR;

  // Shows the progression along the path through `names` (the node selects' when absent):
  // sphere i at t = i / (count − 1) of the piecewise-linear path, as render::ProcessPath::at.
  async function setGrid(names) {
    names = names || [0, 1, 2, 3].map((i) => $(`gpu-node-${i}`).value);
    if (!GR.info) GR.info = await (await fetch(`/api/gpu/grid?count=${GR.count}&columns=${GR.columns}&sphere_pixels=128`)).json();
    const nodes = [];
    for (const n of names) nodes.push(await projection(n));
    G.scene = 'grid';
    $('gpu-scene').value = 'grid';
    names.forEach((n, i) => { if ($(`gpu-node-${i}`)) $(`gpu-node-${i}`).value = n; });
    $('gpu-teapot-controls').hidden = true; $('gpu-grid-controls').hidden = false;
    resize(GR.info.camera.width, GR.info.camera.height);
    GR.names = names; GR.nodes = nodes; GR.builtK = 0;
    dirty = true;
  }
  G.setGrid = setGrid;

  function pathAt(nodes, t, k) {
    const s = Math.min(Math.max(t, 0), 1) * (nodes.length - 1);
    const i = Math.min(Math.floor(s), nodes.length - 2), f = s - i;
    const out = new Float32Array(k);
    for (let j = 0; j < k; j++) out[j] = t >= 1 ? nodes[nodes.length - 1][j] : nodes[i][j] + (nodes[i + 1][j] - nodes[i][j]) * f;
    return out;
  }

  function buildGridTexture() {
    const k = Math.min(G.k, ...GR.nodes.map((n) => n.length)), layers = Math.ceil(k / 4), n = GR.count;
    const data = new Float32Array(layers * n * 4);
    for (let i = 0; i < n; i++) {
      const c = pathAt(GR.nodes, i / (n - 1), k);
      for (let j = 0; j < k; j++) data[(Math.floor(j / 4) * n + i) * 4 + (j % 4)] = c[j];
    }
    if (GR.coefTex) gl.deleteTexture(GR.coefTex);
    GR.coefTex = gl.createTexture();
    gl.activeTexture(gl.TEXTURE6); gl.bindTexture(gl.TEXTURE_2D_ARRAY, GR.coefTex);
    gl.texImage3D(gl.TEXTURE_2D_ARRAY, 0, gl.RGBA32F, n, 1, layers, 0, gl.RGBA, gl.FLOAT, data);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.activeTexture(gl.TEXTURE0);
    GR.builtK = k;
  }

  function drawGrid(W, H, index) {
    if (GR.builtK !== Math.min(G.k, ...GR.nodes.map((n) => n.length))) { buildGridTexture(); bindAll(); }
    const u = gridProg.u, info = GR.info;
    gl.useProgram(gridProg.p);
    setUniforms(u);
    gl.uniform2f(u.uSize, W, H); gl.uniform1i(u.uFrame, index);
    gl.uniform1i(u.uK, GR.builtK); gl.uniform1i(u.uVarying, 1);
    gl.uniform1i(u.uSpheres, info.centres.length);
    gl.uniform3fv(u.uCentres, new Float32Array(info.centres.flat()));
    gl.uniform3f(u.uCamPos, ...info.camera.position);
    gl.uniform1f(u.uTanHalf, Math.tan((info.camera.fov_degrees * Math.PI) / 360));
    gl.uniform3f(u.uLight, ...info.light.position);
    gl.uniform3f(u.uIntensity, ...info.light.intensity);
    gl.enable(gl.BLEND); gl.blendFunc(gl.ONE, gl.ONE);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    gl.disable(gl.BLEND);
  }

  // The brush: paints rust (the path position) or a trait edit around the uv under the pointer.
  function brushAt(x, y) {
    if (!T.uv) return;
    const px = ((G.height - 1 - y) * G.width + x) * 4;
    if (T.uv[px + 2] < 0.5) return; // background
    const u = T.uv[px], v = T.uv[px + 1];
    const mode = $('gpu-brush').value, radius = 10;
    const cx = u * T.tw - 0.5, cy = v * T.th - 0.5;
    let field = T.field, amount = 0.12;
    if (mode !== 'rust+' && mode !== 'rust-') {
      const [name, sign] = [mode.slice(0, -1), mode.endsWith('+') ? 1 : -1];
      field = T.offsets[name] = T.offsets[name] || new Float32Array(T.tw * T.th);
      amount = 0.25 * sign;
    } else if (mode === 'rust-') amount = -amount;
    for (let dy = -radius; dy <= radius; dy++) for (let dx = -radius; dx <= radius; dx++) {
      const d = Math.hypot(dx, dy) / radius;
      if (d > 1) continue;
      const tx = ((Math.round(cx) + dx) % T.tw + T.tw) % T.tw, ty = Math.round(cy) + dy;
      if (ty < 0 || ty >= T.th) continue;
      const i = ty * T.tw + tx, w = amount * (1 - d * d);
      field[i] = field === T.field ? Math.min(1, Math.max(0, field[i] + w)) : field[i] + w;
    }
    T.dirtyTexture = true; dirty = true; T.pendingPreview = true;
    G.brushStrokes = (G.brushStrokes || 0) + 1;
  }
  G.brushAt = brushAt;

  // Waits for the GPU: a one-pixel read of the drawn canvas.
  function sync() {
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    const px = new Uint8Array(4); gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
  }

  let fpsWindow = [], band = 0, bandStart = 0, bandWork = 0;
  function loop() {
    requestAnimationFrame(loop);
    if (!G.ready || !G.material || G.tabHidden) return;
    if (dirty) { G.frames = 0; band = 0; dirty = false; G.target = G.mode === 'env' ? G.envFrames : G.pointFrames; }
    if (G.frames >= G.target) return;
    // While an edit is on its way to the server, its first image has the GPU to itself.
    if (G.pendingInputs.length || window.gantry.editing) return;
    // While the brush paints, its strokes show at once, small.
    if (T.pendingPreview) { T.pendingPreview = false; frame(true); return; }
    if (band === 0) { bandStart = performance.now(); bandWork = 0; }
    const t0 = performance.now();
    frame(false, band);
    sync();
    bandWork += performance.now() - t0;
    band = (band + 1) % BANDS;
    if (band !== 0) return;
    const now = performance.now();
    if (G.frames === 1 && G.pendingFull.length) {
      for (const t of G.pendingFull) G.fullLatencies.push(now - t);
      G.pendingFull = [];
    }
    G.frameMs.push(now - bandStart); if (G.frameMs.length > 200) G.frameMs.shift();
    // Cost per pixel of this material and light (the preview's size follows it).
    const perPixel = bandWork / (G.width * G.height);
    G.msPerPixel = G.msPerPixel > 0 ? 0.5 * (G.msPerPixel + perPixel) : perPixel;
    fpsWindow.push(now); while (fpsWindow[0] < now - 1000) fpsWindow.shift();
    $('gpu-fps').textContent = `${fpsWindow.length} frames/s · ${G.frames}/${G.target} ${G.mode === 'env' ? `frames of ${ENV_SAMPLES} samples` : 'jittered frames'}`;
  }

  // The material to draw: its coefficients (from an edit session's state) or a fetch.
  async function setMaterial(name, coefficients, predicted) {
    if (!G.available) return;
    // The server's answer to a step already drawn from its prediction: nothing to redraw
    // unless a check stopped the step.
    if (!predicted && coefficients && name === G.material && G.predicted && sameCoefficients(coefficients, G.coefficients)) {
      G.predicted = false; G.confirmed++; return;
    }
    if (!predicted && G.predicted && name === G.material) G.corrected++;
    G.predicted = !!predicted;
    G.material = name;
    if (!coefficients) {
      const r = await fetch(`/api/gpu/materials/${encodeURIComponent(name)}/coefficients`);
      if (!r.ok) { setStatus(`cannot project ${name}: ${(await r.json()).error || r.status}`); return; }
      if (G.material !== name) return;
      coefficients = (await r.json()).coefficients;
    }
    G.coefficients = coefficients.slice(0, MAX_K);
    dirty = true;
    // The first image of the new material now, small; the full one follows frame by frame.
    if (G.pendingInputs.length) {
      frame(true);
      sync();
      const now = performance.now();
      for (const t of G.pendingInputs) G.latencies.push(now - t);
      G.pendingFull.push(...G.pendingInputs);
      G.pendingInputs = [];
    }
  }

  function sameCoefficients(a, b) {
    if (a.length !== b.length && Math.min(a.length, MAX_K) !== b.length) return false;
    let scale = 0, diff = 0;
    for (let j = 0; j < b.length; j++) { scale = Math.max(scale, Math.abs(a[j])); diff = Math.max(diff, Math.abs(a[j] - b[j])); }
    return diff <= 1e-9 * Math.max(1, scale);
  }

  // Measures the frame time with the GPU waited for after each frame: median over `frames`.
  G.benchmark = function (opts) {
    const saved = { k: G.k, mode: G.mode };
    if (opts.k != null) G.k = opts.k;
    if (opts.mode) G.mode = opts.mode;
    const times = [];
    G.frames = 0;
    for (let i = 0; i < (opts.frames || 10); i++) {
      const t0 = performance.now(); frame(!!opts.preview); sync(); times.push(performance.now() - t0);
    }
    G.k = saved.k; G.mode = saved.mode; dirty = true;
    times.sort((a, b) => a - b);
    return { median: times[Math.floor(times.length / 2)], all: times };
  };

  // The accumulated linear image (RGB, rows top to bottom) and its frame count.
  G.readLinear = function () {
    const W = G.width, H = G.height;
    const px = new Float32Array(W * H * 4);
    gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
    gl.readPixels(0, 0, W, H, gl.RGBA, gl.FLOAT, px);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    const out = new Array(W * H * 3);
    for (let y = 0; y < H; y++) for (let x = 0; x < W; x++) {
      const s = ((H - 1 - y) * W + x) * 4, d = (y * W + x) * 3;
      for (let c = 0; c < 3; c++) out[d + c] = px[s + c] / G.frames;
    }
    return { width: W, height: H, frames: G.frames, pixels: out };
  };
  G.converged = () => G.ready && !dirty && G.frames >= G.target;
  G.setMaterial = setMaterial;
  G.restart = () => { dirty = true; };

  function setupControls() {
    $('gpu-k').addEventListener('input', () => { G.k = parseInt($('gpu-k').value, 10); $('gpu-k-out').textContent = `k = ${G.k}`; dirty = true; });
    $('gpu-mode').addEventListener('change', () => { G.mode = $('gpu-mode').value; dirty = true; });
    $('gpu-smooth').addEventListener('change', () => { G.smooth = $('gpu-smooth').checked; lobeKey = ''; dirty = true; });
    $('gpu-exposure').addEventListener('input', () => {
      G.exposure = parseFloat($('gpu-exposure').value);
      $('gpu-exposure-out').textContent = `${G.exposure > 0 ? '+' : ''}${G.exposure} EV`;
      if (G.frames > 0) { bindAll(); gl.useProgram(show.p); gl.uniform1f(show.u.uRatio, 1); gl.uniform1f(show.u.uScale, 2 ** G.exposure / G.frames); gl.drawArrays(gl.TRIANGLES, 0, 3); }
      else dirty = true;
    });
    $('gpu-scene').addEventListener('change', () => setScene($('gpu-scene').value).catch((e) => { setStatus(e.message); $('gpu-scene').value = G.scene; }));
    for (const id of ['gpu-from', 'gpu-to']) $(id).addEventListener('change', () => setScene(G.scene).catch((e) => setStatus(e.message)));
    for (let i = 0; i < 4; i++) $(`gpu-node-${i}`).addEventListener('change', () => setGrid().catch((e) => setStatus(e.message)));
    $('gpu-probe-file').addEventListener('change', () => {
      const f = $('gpu-probe-file').files[0];
      if (f) uploadProbe(f).catch((e) => setStatus(`probe ${f.name}: ${e.message}`));
    });
    const c = $('gpu-canvas');
    let down = false;
    const R = Math.hypot(...SPHERE_LIGHT);
    const move = (ev) => {
      const r = c.getBoundingClientRect();
      if (G.scene === 'grid') return;
      if (MESHES.includes(G.scene)) {
        brushAt(Math.floor(((ev.clientX - r.left) / r.width) * G.width), Math.floor(((ev.clientY - r.top) / r.height) * G.height));
        return;
      }
      let x = ((ev.clientX - r.left) / r.width) * 2 - 1, y = 1 - ((ev.clientY - r.top) / r.height) * 2;
      const n = Math.hypot(x, y); if (n > 0.995) { x *= 0.995 / n; y *= 0.995 / n; }
      G.light = [R * x, R * y, R * Math.sqrt(Math.max(0, 1 - x * x - y * y))];
      dirty = true;
    };
    c.addEventListener('pointerdown', (ev) => { down = true; c.setPointerCapture(ev.pointerId); move(ev); });
    c.addEventListener('pointermove', (ev) => { if (down) move(ev); });
    c.addEventListener('pointerup', () => { down = false; });
  }

  async function start() {
    try {
      G.available = init();
    } catch (e) { G.available = false; G.reason = e.message; }
    if (!G.available) {
      $('gpu-card').classList.add('off');
      setStatus(`${G.reason}: the CPU previews beside it are shown instead.`);
      return;
    }
    setupControls();
    requestAnimationFrame(loop);
    try {
      await loadBasis();
      await loadEnvironment();
      G.ready = true;
      await fillTeapotControls();
      const mb = (G.memoryBytes / 1048576).toFixed(1);
      setStatus(`WebGL2: mean + ${G.components} components, ${TH}×${TD}×${PD} (θh×θd×φd) half-float RGB, ${mb} MB`);
      if (G.wanted) setMaterial(...G.wanted);
    } catch (e) {
      G.error = e.message;
      setStatus(e.message.includes('model') ? 'The real-time view needs a model: gantry serve --model model.bin' : `real-time view: ${e.message}`);
    }
  }
  // The teapot's material choices (corpus materials; rust-coloured defaults where present) and
  // brush modes (rust, and each linear-space trait up or down).
  async function fillTeapotControls() {
    const names = (await (await fetch('/api/materials')).json()).materials.map((m) => m.name);
    const pick = (sel, wanted) => {
      for (const n of names) { const o = document.createElement('option'); o.value = n; o.textContent = n; sel.append(o); }
      sel.value = wanted.find((w) => names.includes(w)) || names[0];
    };
    pick($('gpu-from'), ['aluminium', 'steel', 'nickel', 'chrome']);
    pick($('gpu-to'), ['light-brown-fabric', 'colonial-maple-223', 'cherry-235', 'red-fabric', names[1]]);
    // The progression: polished to black oxidized steel through two steels between (the
    // thesis measured four stages of one sample; these are four MERL materials).
    const path = ['chrome-steel', 'steel', 'grease-covered-steel', 'black-oxidized-steel'];
    path.forEach((n, i) => pick($(`gpu-node-${i}`), [n, names[Math.min(i, names.length - 1)]]));
    const info = window.gantry.state && window.gantry.state.info;
    T.steps = {};
    const brush = $('gpu-brush');
    for (const t of (info && info.spaces[0] ? info.spaces[0].traits : [])) {
      if (!t.unit_step) continue;
      T.steps[t.name] = t.unit_step;
      for (const sign of ['+', '-']) { const o = document.createElement('option'); o.value = t.name + sign; o.textContent = `${t.name} ${sign === '+' ? 'up' : 'down'}`; brush.append(o); }
    }
  }

  // The page calls this whenever the shown material or the edit session changes.
  window.gantry.gpuShow = (name, coefficients, predicted) => {
    G.wanted = [name, coefficients];
    if (G.ready) setMaterial(name, coefficients, predicted);
  };
  // An input event's time (its timeStamp: when the browser made it, so time spent waiting for
  // the page counts too).
  window.gantry.gpuInput = (at) => { if (G.available) G.pendingInputs.push(at ?? performance.now()); };
  if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', start); else start();
})();
