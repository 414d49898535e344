// painterly preview: the page. Plain WebGL2, no framework, no network
// beyond this server. Frames are evaluated by the server (the same code as
// `painterly bake`); this page only draws them and sends what the artist
// changes: time, pinned axis values, the orbit camera. Protocol:
// docs/preview.md.
'use strict';

(() => {
  const $ = (id) => document.getElementById(id);
  const MAGIC = 0x594c5450; // "PTLY" little-endian

  // What tests and scripts can look at.
  const api = (window.painterly = {
    ready: false,
    framesDrawn: 0,
    lastHeader: null,
    roundTrips: [],
    errors: [],
    // True once the server closed the websocket (see `lost`).
    lost: false,
  });

  // ---------- protocol ----------
  function decode(buf) {
    const dv = new DataView(buf);
    if (buf.byteLength < 8 || dv.getUint32(0, true) !== MAGIC) throw new Error('not a painterly frame');
    const n = dv.getUint32(4, true);
    const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 8, n)));
    const base = 8 + n;
    const arrays = {};
    for (const [name, [off, len]] of Object.entries(header.arrays)) {
      arrays[name] = new Float32Array(buf, base + off * 4, len);
    }
    return { header, arrays };
  }

  // ---------- small matrix helpers (column-major, like WebGL) ----------
  const v3 = {
    sub: (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]],
    add: (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]],
    scale: (a, s) => [a[0] * s, a[1] * s, a[2] * s],
    dot: (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2],
    cross: (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]],
    len: (a) => Math.hypot(a[0], a[1], a[2]),
    norm: (a) => {
      const l = Math.hypot(a[0], a[1], a[2]) || 1;
      return [a[0] / l, a[1] / l, a[2] / l];
    },
  };
  function lookAt(eye, target, up) {
    const z = v3.norm(v3.sub(eye, target));
    let x = v3.cross(up, z);
    if (v3.len(x) < 1e-9) x = v3.cross([1, 0, 0], z);
    x = v3.norm(x);
    const y = v3.cross(z, x);
    return new Float32Array([
      x[0], y[0], z[0], 0,
      x[1], y[1], z[1], 0,
      x[2], y[2], z[2], 0,
      -v3.dot(x, eye), -v3.dot(y, eye), -v3.dot(z, eye), 1,
    ]);
  }
  function perspective(fovY, aspect, near, far) {
    const f = 1 / Math.tan((fovY * Math.PI) / 360);
    const nf = 1 / (near - far);
    return new Float32Array([f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0]);
  }

  // ---------- GL ----------
  const canvas = $('live');
  const gl = canvas.getContext('webgl2', { antialias: true, preserveDrawingBuffer: true, premultipliedAlpha: false });
  if (!gl) {
    fail('this browser has no WebGL2');
    return;
  }

  function shader(type, src) {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }
  function program(vs, fs) {
    const p = gl.createProgram();
    gl.attachShader(p, shader(gl.VERTEX_SHADER, vs));
    gl.attachShader(p, shader(gl.FRAGMENT_SHADER, fs));
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
    const u = {};
    const n = gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS);
    for (let i = 0; i < n; i++) {
      const name = gl.getActiveUniform(p, i).name;
      u[name] = gl.getUniformLocation(p, name);
    }
    return { p, u };
  }

  const SRGB = `
    vec3 srgb(vec3 c) {
      c = clamp(c, 0.0, 1.0);
      return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, c));
    }`;

  // Camera-facing ribbons: one instance per segment (point i to i+1), four
  // vertices; the ribbon is `width` wide perpendicular to the segment and
  // to the ray from the eye, as painterly render draws strokes.
  const ribbonProg = program(
    `#version 300 es
    layout(location=0) in vec3 p0; layout(location=1) in vec3 p1;
    layout(location=2) in float w0; layout(location=3) in float w1;
    layout(location=4) in vec3 c0; layout(location=5) in vec3 c1;
    layout(location=6) in float o0; layout(location=7) in float o1;
    layout(location=8) in float valid;
    uniform mat4 model, view, proj;
    out vec4 vColor; out float vSide;
    void main() {
      if (valid < 0.5) { gl_Position = vec4(2.0, 2.0, 2.0, 1.0); return; }
      int id = gl_VertexID;
      bool end = id >= 2;
      float side = (id == 0 || id == 2) ? -1.0 : 1.0;
      vec3 a = (view * model * vec4(p0, 1.0)).xyz;
      vec3 b = (view * model * vec4(p1, 1.0)).xyz;
      vec3 p = end ? b : a;
      vec3 d = b - a;
      vec3 s = cross(d, p);
      float sl = length(s);
      s = sl > 1e-12 ? s / sl : vec3(0.0);
      // Widths come in the layer's own space: scaled as render scales them,
      // by the cube root of the frame's transform's volume change.
      float w = (end ? w1 : w0) * pow(abs(determinant(mat3(model))), 1.0 / 3.0);
      gl_Position = proj * vec4(p + s * 0.5 * w * side, 1.0);
      vColor = vec4(end ? c1 : c0, end ? o1 : o0);
      vSide = side;
    }`,
    `#version 300 es
    precision highp float;
    in vec4 vColor; in float vSide; out vec4 frag;
    ${SRGB}
    void main() {
      float e = fwidth(vSide);
      float cover = 1.0 - smoothstep(1.0 - 1.5 * e, 1.0, abs(vSide));
      frag = vec4(srgb(vColor.rgb), vColor.a * cover);
    }`
  );

  // Rademacher's warm/cool shading, lights fixed in camera space (as in
  // painterly render: k_a = 0.9, k1..k4 = 1).
  const meshProg = program(
    `#version 300 es
    layout(location=0) in vec3 pos; layout(location=1) in vec3 nrm;
    uniform mat4 model, view, proj;
    out vec3 vN; out vec3 vP;
    void main() {
      vec4 p = view * model * vec4(pos, 1.0);
      vP = p.xyz;
      vN = mat3(view) * mat3(model) * nrm;
      gl_Position = proj * p;
    }`,
    `#version 300 es
    precision highp float;
    in vec3 vN; in vec3 vP; out vec4 frag;
    uniform vec3 base; uniform float alpha;
    ${SRGB}
    void main() {
      vec3 n = normalize(vN);
      if (dot(n, -vP) < 0.0) n = -n;
      vec3 l1 = normalize(vec3(-0.5, 0.6, 0.62));
      vec3 warm = vec3(0.95, 0.62, 0.30), cool = vec3(0.18, 0.26, 0.55);
      vec3 c = 0.9 * base + max(dot(l1, n), 0.0) * (warm - base) + max(dot(-l1, n), 0.0) * (cool - base);
      frag = vec4(srgb(c), alpha);
    }`
  );

  // ---------- scene state ----------
  let scene = null;
  const layers = []; // {info, vao, buffers, n, visible, opacityPerPoint}
  const views = []; // {info, tris, vao, buf, count}
  const proxies = [];
  const state = {
    time: 0,
    overrides: {},
    viewDrives: false,
    showProxy: false,
    showBake: false,
    playing: false,
  };
  let frame = null; // last decoded frame
  api.state = state;

  // ---------- orbit camera ----------
  // aspect: width / height of the frame the view starts on (the USD
  // camera's, or 1 around the bounds).
  const orbit = { target: [0, 0, 0], up: [0, 1, 0], yaw: 0, pitch: 0, dist: 10, fovY: 40, aspect: 1 };
  // The vertical field of view in a pane of this aspect. A pane narrower
  // than the camera's frame widens it so the whole frame stays in view
  // (CameraUtil's Fit): with the render pane open the live view is half as
  // wide, and the camera's framing must not be cut at the sides.
  function fovYFor(paneAspect) {
    if (!(paneAspect > 0) || paneAspect >= orbit.aspect) return orbit.fovY;
    const t = Math.tan((orbit.fovY * Math.PI) / 360) * (orbit.aspect / paneAspect);
    return (Math.atan(t) * 360) / Math.PI;
  }
  function canvasAspect() {
    return canvas.clientHeight > 0 ? canvas.clientWidth / canvas.clientHeight : 1;
  }
  function basis() {
    const up = v3.norm(orbit.up);
    let e1 = v3.cross(up, [0, 0, 1]);
    if (v3.len(e1) < 1e-6) e1 = v3.cross(up, [1, 0, 0]);
    e1 = v3.norm(e1);
    const e2 = v3.cross(e1, up);
    return { up, e1, e2 };
  }
  function eye() {
    const { up, e1, e2 } = basis();
    const cp = Math.cos(orbit.pitch);
    const dir = v3.add(v3.add(v3.scale(e2, cp * Math.cos(orbit.yaw)), v3.scale(e1, cp * Math.sin(orbit.yaw))), v3.scale(up, Math.sin(orbit.pitch)));
    return v3.add(orbit.target, v3.scale(dir, orbit.dist));
  }
  function setOrbitFrom(position, target, up) {
    orbit.target = target.slice();
    orbit.up = up.slice();
    const { up: u, e1, e2 } = basis();
    const d = v3.sub(position, target);
    orbit.dist = Math.max(v3.len(d), 1e-6);
    const n = v3.norm(d);
    orbit.pitch = Math.asin(Math.max(-1, Math.min(1, v3.dot(n, u))));
    orbit.yaw = Math.atan2(v3.dot(n, e1), v3.dot(n, e2));
  }
  function cameraPose(paneAspect = canvasAspect()) {
    const e = eye();
    const near = orbit.dist * 0.01;
    const far = orbit.dist * 100 + sceneRadius() * 4;
    const { up } = basis();
    return { position: e, target: orbit.target.slice(), up, fov_y: fovYFor(paneAspect), near, far };
  }
  function sceneRadius() {
    if (!scene) return 1;
    return Math.max(v3.len(v3.sub(scene.bounds[1], scene.bounds[0])) * 0.5, 1e-3);
  }
  api.orbit = orbit;
  api.cameraPose = cameraPose;

  let drag = null;
  canvas.addEventListener('pointerdown', (e) => {
    drag = { x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button === 2 };
    canvas.setPointerCapture(e.pointerId);
  });
  canvas.addEventListener('pointermove', (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x;
    const dy = e.clientY - drag.y;
    drag.x = e.clientX;
    drag.y = e.clientY;
    if (drag.pan) {
      const { up, e1, e2 } = basis();
      const k = (orbit.dist * 2 * Math.tan((fovYFor(canvasAspect()) * Math.PI) / 360)) / canvas.clientHeight;
      const fwd = v3.norm(v3.sub(orbit.target, eye()));
      const right = v3.norm(v3.cross(fwd, up));
      const camUp = v3.cross(right, fwd);
      orbit.target = v3.add(orbit.target, v3.add(v3.scale(right, -dx * k), v3.scale(camUp, dy * k)));
      void e1;
      void e2;
    } else {
      orbit.yaw -= dx * 0.008;
      orbit.pitch = Math.max(-1.55, Math.min(1.55, orbit.pitch + dy * 0.008));
    }
    viewChanged();
  });
  const endDrag = () => (drag = null);
  canvas.addEventListener('pointerup', endDrag);
  canvas.addEventListener('pointercancel', endDrag);
  canvas.addEventListener('contextmenu', (e) => e.preventDefault());
  canvas.addEventListener(
    'wheel',
    (e) => {
      e.preventDefault();
      orbit.dist = Math.max(1e-4, orbit.dist * Math.exp(e.deltaY * 0.001));
      viewChanged();
    },
    { passive: false }
  );
  function viewChanged() {
    draw();
    if (state.viewDrives) request();
  }

  // ---------- requests: one in flight, the latest state wins ----------
  let socket = null;
  // Set when the websocket to the server closes: the server stopped (or was
  // restarted, perhaps on another file), so its frames no longer match this
  // page's scene, and no more are asked for.
  let lost = null;
  let inFlight = null; // {id, sent}
  let dirty = false;
  let nextId = 1;
  function frameRequest() {
    return {
      id: nextId++,
      time: state.time,
      overrides: { ...state.overrides },
      eye: state.viewDrives ? eye() : null,
      proxy: state.showProxy,
      bake: state.showBake,
    };
  }
  function request() {
    dirty = true;
    pump();
  }
  function pump() {
    if (lost) {
      setStatus(lost, true);
      return;
    }
    if (inFlight || !dirty || !scene) return;
    dirty = false;
    const req = frameRequest();
    inFlight = { id: req.id, sent: performance.now() };
    if (socket && socket.readyState === WebSocket.OPEN) {
      socket.send(JSON.stringify(req));
    } else {
      fetch('api/frame', { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(req) })
        .then(async (r) => {
          if (!r.ok) throw new Error((await r.json()).error || r.statusText);
          return r.arrayBuffer();
        })
        .then(received, (e) => {
          // fetch's TypeError: no server answers. A server started again
          // on this port may serve another scene (see `lost`).
          if (e instanceof TypeError) {
            lost = 'the preview server cannot be reached: reload this page once painterly preview runs again';
            api.lost = true;
          }
          failed(e.message);
        });
    }
  }
  function received(buf) {
    const rt = inFlight ? performance.now() - inFlight.sent : 0;
    inFlight = null;
    try {
      frame = decode(buf);
    } catch (e) {
      failed(e.message);
      return;
    }
    api.lastHeader = frame.header;
    api.roundTrips.push(rt);
    if (api.roundTrips.length > 1000) api.roundTrips.shift();
    applyFrame(frame, rt);
    pump();
  }
  function failed(message) {
    inFlight = null;
    api.errors.push(message);
    setStatus(message, true);
    pump();
  }
  function openSocket() {
    return new Promise((resolve) => {
      let ws;
      try {
        ws = new WebSocket(new URL('api/ws', location.href.replace(/^http/, 'ws')));
      } catch (e) {
        resolve(null);
        return;
      }
      ws.binaryType = 'arraybuffer';
      ws.onopen = () => resolve(ws);
      ws.onerror = () => resolve(null);
      ws.onclose = () => {
        if (socket === ws) {
          socket = null;
          lost = 'the preview server closed the connection: reload this page once painterly preview runs again';
          api.lost = true;
        }
        if (inFlight) failed('connection to the preview server closed');
        else if (lost) setStatus(lost, true);
      };
      ws.onmessage = (m) => {
        if (typeof m.data === 'string') {
          const e = JSON.parse(m.data);
          failed(`${e.status}: ${e.error}`);
        } else {
          received(m.data);
        }
      };
    });
  }

  // ---------- applying a frame ----------
  function applyFrame(f, rt) {
    const h = f.header;
    // What `painterly render` would not draw at this time (USD visibility,
    // guide or proxy purpose) is not drawn here either.
    const hidden = h.hidden || { layers: [], views: [] };
    views.forEach((V, i) => (V.hidden = hidden.views.includes(i)));
    layers.forEach((L, i) => {
      L.hidden = hidden.layers.includes(i);
      if (L.row) {
        L.row.classList.toggle('hidden-now', L.hidden);
        L.row.title = L.hidden ? `${L.info.path}: invisible at this time (or a guide), so not drawn, as in painterly render` : L.info.path;
      }
      const pts = f.arrays[`layer/${i}/points`];
      const op = f.arrays[`layer/${i}/opacity`];
      const xf = f.arrays[`layer/${i}/xform`];
      if (pts && pts.length === L.n * 3) {
        gl.bindBuffer(gl.ARRAY_BUFFER, L.buffers.points);
        gl.bufferSubData(gl.ARRAY_BUFFER, 0, pts);
        L.hasPoints = true;
      } else {
        L.hasPoints = false;
      }
      if (op && op.length === L.info.curve_counts.length) {
        let k = 0;
        L.info.curve_counts.forEach((c, s) => {
          for (let j = 0; j < c; j++) L.opacity[k++] = op[s];
        });
        gl.bindBuffer(gl.ARRAY_BUFFER, L.buffers.opacity);
        gl.bufferSubData(gl.ARRAY_BUFFER, 0, L.opacity);
      }
      if (xf) L.model = new Float32Array(xf);
    });
    views.forEach((V, i) => updateMesh(V, f.arrays[`view/${i}/points`], f.arrays[`view/${i}/xform`]));
    proxies.forEach((P, i) => updateMesh(P, f.arrays[`proxy/${i}/points`], f.arrays[`proxy/${i}/xform`]));
    if (h.configuration) updateSliders(h.configuration);
    if (h.weights) showWeights(h.weights);
    const t = h.timing || {};
    const server = h.source === 'bake' ? `bake read ${fmt(t.total_ms)} ms` : `server ${fmt(t.total_ms)} ms (read ${fmt(t.read_ms)}, evaluate ${fmt(t.evaluate_ms)})`;
    setStatus(h.stale ? h.stale : `t=${h.time} · ${server} · round trip ${fmt(rt)} ms`, !!h.stale);
    draw();
    api.framesDrawn++;
  }
  const fmt = (x) => (x === undefined ? '–' : x.toFixed(1));

  // Triangulated soup with per-corner normals (smooth: area-weighted vertex
  // normals; faceted: the face's), rebuilt per frame: view-dependent meshes
  // change shape with every frame.
  function updateMesh(M, pts, xf) {
    if (!pts) {
      M.count = 0;
      return;
    }
    M.points = pts;
    if (xf) M.model = new Float32Array(xf);
    const nv = pts.length / 3;
    const tris = M.tris;
    const out = new Float32Array(tris.length * 6);
    const fn = new Float32Array(tris.length); // face normals, 3 per triangle
    const vn = M.info.smooth ? new Float32Array(nv * 3) : null;
    for (let t = 0; t < tris.length; t += 3) {
      const a = tris[t] * 3, b = tris[t + 1] * 3, c = tris[t + 2] * 3;
      if (a >= pts.length || b >= pts.length || c >= pts.length) continue;
      const ux = pts[b] - pts[a], uy = pts[b + 1] - pts[a + 1], uz = pts[b + 2] - pts[a + 2];
      const wx = pts[c] - pts[a], wy = pts[c + 1] - pts[a + 1], wz = pts[c + 2] - pts[a + 2];
      const nx = uy * wz - uz * wy, ny = uz * wx - ux * wz, nz = ux * wy - uy * wx;
      fn[t] = nx; fn[t + 1] = ny; fn[t + 2] = nz;
      if (vn) for (const i of [a, b, c]) { vn[i] += nx; vn[i + 1] += ny; vn[i + 2] += nz; }
    }
    for (let t = 0; t < tris.length; t++) {
      const i = tris[t] * 3;
      const o = t * 6;
      out[o] = pts[i]; out[o + 1] = pts[i + 1]; out[o + 2] = pts[i + 2];
      const f = t - (t % 3);
      if (vn) { out[o + 3] = vn[i]; out[o + 4] = vn[i + 1]; out[o + 5] = vn[i + 2]; }
      else { out[o + 3] = fn[f]; out[o + 4] = fn[f + 1]; out[o + 5] = fn[f + 2]; }
    }
    gl.bindBuffer(gl.ARRAY_BUFFER, M.buf);
    gl.bufferData(gl.ARRAY_BUFFER, out, gl.DYNAMIC_DRAW);
    M.count = tris.length;
  }

  function fan(counts, indices) {
    const tris = [];
    let k = 0;
    for (const c of counts) {
      for (let j = 1; j + 1 < c; j++) tris.push(indices[k], indices[k + j], indices[k + j + 1]);
      k += c;
    }
    return new Uint32Array(tris);
  }
  function makeMesh(info) {
    const vao = gl.createVertexArray();
    const buf = gl.createBuffer();
    gl.bindVertexArray(vao);
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 24, 0);
    gl.enableVertexAttribArray(1);
    gl.vertexAttribPointer(1, 3, gl.FLOAT, false, 24, 12);
    gl.bindVertexArray(null);
    return { info, tris: fan(info.face_counts, info.face_indices), vao, buf, count: 0, model: new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]) };
  }

  function makeLayer(info, widths, colors) {
    const n = info.points;
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const buffer = (data, usage) => {
      const b = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, b);
      gl.bufferData(gl.ARRAY_BUFFER, data, usage);
      return b;
    };
    // Instance i reads point i (locations 0, 2, 4, 6) and point i + 1 (1, 3, 5, 7).
    const pair = (b, loc, size) => {
      gl.bindBuffer(gl.ARRAY_BUFFER, b);
      for (const [l, off] of [[loc, 0], [loc + 1, size * 4]]) {
        gl.enableVertexAttribArray(l);
        gl.vertexAttribPointer(l, size, gl.FLOAT, false, size * 4, off);
        gl.vertexAttribDivisor(l, 1);
      }
    };
    const points = buffer(new Float32Array(n * 3 + 3), gl.DYNAMIC_DRAW);
    const w = new Float32Array(n + 1);
    w.set(widths);
    const c = new Float32Array(n * 3 + 3);
    c.set(colors);
    const opacity = new Float32Array(n + 1).fill(1);
    const valid = new Float32Array(n);
    let k = 0;
    for (const count of info.curve_counts) {
      for (let j = 0; j + 1 < count; j++) valid[k + j] = 1;
      k += count;
    }
    const buffers = {
      points,
      widths: buffer(w, gl.STATIC_DRAW),
      colors: buffer(c, gl.STATIC_DRAW),
      opacity: buffer(opacity, gl.DYNAMIC_DRAW),
      valid: buffer(valid, gl.STATIC_DRAW),
    };
    pair(buffers.points, 0, 3);
    pair(buffers.widths, 2, 1);
    pair(buffers.colors, 4, 3);
    pair(buffers.opacity, 6, 1);
    gl.bindBuffer(gl.ARRAY_BUFFER, buffers.valid);
    gl.enableVertexAttribArray(8);
    gl.vertexAttribPointer(8, 1, gl.FLOAT, false, 4, 0);
    gl.vertexAttribDivisor(8, 1);
    gl.bindVertexArray(null);
    return { info, vao, buffers, n, visible: true, hasPoints: false, opacity: new Float32Array(n), model: new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]) };
  }

  // ---------- drawing ----------
  let drawQueued = false;
  function draw() {
    if (drawQueued) return;
    drawQueued = true;
    requestAnimationFrame(() => {
      drawQueued = false;
      drawNow();
    });
  }
  function drawNow() {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(canvas.clientWidth * dpr));
    const h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) {
      canvas.width = w;
      canvas.height = h;
    }
    gl.viewport(0, 0, w, h);
    gl.clearColor(0.945, 0.929, 0.894, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    if (!scene) return;
    const cam = cameraPose();
    const view = lookAt(cam.position, cam.target, cam.up);
    const proj = perspective(cam.fov_y, w / h, cam.near, cam.far);
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LEQUAL);
    gl.disable(gl.CULL_FACE);

    // Opaque view-dependent meshes first, writing depth.
    gl.useProgram(meshProg.p);
    gl.uniformMatrix4fv(meshProg.u.view, false, view);
    gl.uniformMatrix4fv(meshProg.u.proj, false, proj);
    gl.disable(gl.BLEND);
    gl.depthMask(true);
    for (const V of views) {
      if (!V.count || V.hidden) continue;
      gl.uniformMatrix4fv(meshProg.u.model, false, V.model);
      gl.uniform3fv(meshProg.u.base, V.info.color);
      gl.uniform1f(meshProg.u.alpha, 1);
      gl.bindVertexArray(V.vao);
      gl.drawArrays(gl.TRIANGLES, 0, V.count);
    }

    // Strokes: alpha-blended ribbons in stage order, depth-tested.
    gl.enable(gl.BLEND);
    gl.blendFuncSeparate(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA, gl.ONE, gl.ONE_MINUS_SRC_ALPHA);
    gl.depthMask(false);
    gl.useProgram(ribbonProg.p);
    gl.uniformMatrix4fv(ribbonProg.u.view, false, view);
    gl.uniformMatrix4fv(ribbonProg.u.proj, false, proj);
    for (const L of layers) {
      if (!L.visible || L.hidden || !L.hasPoints || L.n < 2) continue;
      gl.uniformMatrix4fv(ribbonProg.u.model, false, L.model);
      gl.bindVertexArray(L.vao);
      gl.drawArraysInstanced(gl.TRIANGLE_STRIP, 0, 4, L.n - 1);
    }

    // The proxy, translucent, on top.
    if (state.showProxy) {
      gl.useProgram(meshProg.p);
      for (const P of proxies) {
        if (!P.count) continue;
        gl.uniformMatrix4fv(meshProg.u.model, false, P.model);
        gl.uniform3fv(meshProg.u.base, P.info.color);
        gl.uniform1f(meshProg.u.alpha, 0.25);
        gl.bindVertexArray(P.vao);
        gl.drawArrays(gl.TRIANGLES, 0, P.count);
      }
    }
    gl.bindVertexArray(null);
    gl.depthMask(true);
  }
  new ResizeObserver(draw).observe(canvas);

  // ---------- panel ----------
  function setStatus(text, error = false) {
    const s = $('status');
    s.textContent = text;
    s.classList.toggle('error', error);
  }
  function fail(message) {
    setStatus(message, true);
    api.errors.push(message);
  }
  const short = (p) => p.split('/').pop();
  function el(tag, props = {}, children = []) {
    const e = document.createElement(tag);
    Object.assign(e, props);
    for (const c of children) e.append(c);
    return e;
  }

  const sliders = {}; // axis path → {input, out, row, info}
  function buildAxes() {
    const box = $('axes');
    box.textContent = '';
    if (!scene.axes.length) box.append(el('p', { className: 'hint', textContent: 'This character has no axes.' }));
    for (const a of scene.axes) {
      // step=any: a pinned value is exactly what the slider says (no grid).
      const input = el('input', { type: 'range', min: a.min, max: a.max, step: 'any', value: a.min });
      input.setAttribute('aria-label', a.path);
      input.dataset.axis = a.path;
      const out = el('output');
      const release = el('button', { type: 'button', className: 'release', textContent: 'release', title: 'follow the timeline again' });
      const marks = el('div', { className: 'marks' });
      for (const k of a.keys) {
        const pct = ((k.coordinate - a.min) / (a.max - a.min)) * 100;
        const m = el('span', { className: 'mark', textContent: '◆', title: `${short(k.key)} (${k.key}) at ${k.coordinate}` });
        m.style.left = `${pct}%`;
        m.addEventListener('click', () => pin(a.path, k.coordinate));
        marks.append(m);
      }
      const row = el('div', { className: 'axis' }, [
        el('div', { className: 'name' }, [el('b', { textContent: short(a.path), title: a.path }), el('span', { className: 'kind', textContent: a.kind }), out, release]),
        input,
        marks,
      ]);
      input.addEventListener('input', () => pin(a.path, parseFloat(input.value)));
      release.addEventListener('click', () => unpin(a.path));
      sliders[a.path] = { input, out, row, info: a };
      box.append(row);
    }
  }
  function pin(path, value) {
    state.overrides[path] = value;
    const s = sliders[path];
    s.input.value = value;
    s.out.textContent = value.toFixed(3);
    s.row.classList.add('pinned');
    request();
  }
  function unpin(path) {
    delete state.overrides[path];
    sliders[path].row.classList.remove('pinned');
    request();
  }
  api.pin = pin;
  api.unpin = unpin;
  $('release-all').addEventListener('click', () => {
    for (const p of Object.keys(state.overrides)) sliders[p].row.classList.remove('pinned');
    state.overrides = {};
    request();
  });
  function updateSliders(conf) {
    for (const [path, v] of Object.entries(conf)) {
      const s = sliders[path];
      if (!s) continue;
      if (document.activeElement !== s.input || !(path in state.overrides)) s.input.value = v;
      s.out.textContent = Number(v).toFixed(3);
    }
  }

  function showWeights(weights) {
    const box = $('weights');
    box.textContent = '';
    const names = Object.keys(weights);
    if (!names.length) {
      box.append(el('p', { className: 'hint', textContent: 'No keyed layers.' }));
      return;
    }
    for (const layer of names) {
      const w = weights[layer];
      const rows = [];
      for (const [channel, terms] of [['position', w.position], ['opacity', w.opacity]]) {
        for (const [key, weight] of terms) {
          if (key === null && terms.length === 1 && weight === 1) continue;
          const bar = el('span');
          bar.style.width = `${Math.max(0, Math.min(1, Math.abs(weight))) * 100}%`;
          rows.push(
            el('div', { className: 'wrow' }, [
              el('span', { className: 'chan', textContent: channel }),
              el('span', { className: 'key', textContent: key ? short(key) : 'rest', title: key || 'the layer’s own value' }),
              el('div', { className: 'bar' }, [bar]),
              el('span', { className: 'w', textContent: weight.toFixed(2) }),
            ])
          );
        }
      }
      if (!rows.length) rows.push(el('div', { className: 'hint', textContent: 'rest (no key weighs now)' }));
      box.append(el('div', { className: 'weights-layer' }, [el('div', { className: 'lname', textContent: short(layer), title: layer }), ...rows]));
    }
  }

  function buildLayers() {
    const body = $('layers').querySelector('tbody');
    body.textContent = '';
    layers.forEach((L, i) => {
      const info = L.info;
      const box = el('input', { type: 'checkbox', checked: true });
      box.dataset.layer = i;
      box.setAttribute('aria-label', `show ${info.path}`);
      box.addEventListener('change', () => {
        L.visible = box.checked;
        draw();
      });
      const time = info.sentinels ? `${info.time_keys}+${info.sentinels}` : `${info.time_keys}`;
      const cells = [box, short(info.path), info.strokes, info.points, info.pose_position_keys, info.pose_opacity_keys, time];
      L.row = el('tr', { title: info.path }, cells.map((c) => el('td', {}, [c instanceof Node ? c : String(c)])));
      body.append(L.row);
    });
  }

  function buildProblems() {
    const list = $('problems');
    list.textContent = '';
    if (!scene.problems.length) {
      list.append(el('li', { className: 'none', textContent: 'none found' }));
      return;
    }
    for (const p of scene.problems) {
      const where = [p.prim, p.attribute].filter(Boolean).join('.');
      list.append(el('li', { textContent: where ? `${where}: ${p.message}` : p.message }));
    }
  }

  // ---------- timeline ----------
  const timeInput = $('time');
  timeInput.addEventListener('input', () => setTime(parseFloat(timeInput.value)));
  function setTime(t) {
    state.time = t;
    timeInput.value = t;
    $('time-value').textContent = t;
    request();
  }
  api.setTime = setTime;
  $('play').addEventListener('click', () => {
    state.playing = !state.playing;
    $('play').textContent = state.playing ? '❚❚' : '▶';
    $('play').setAttribute('aria-label', state.playing ? 'pause' : 'play');
    lastTick = performance.now();
    if (state.playing) requestAnimationFrame(tick);
  });
  let lastTick = 0;
  function tick(now) {
    if (!state.playing) return;
    const dt = 1000 / (scene.frames_per_second || 24);
    // Advance only once the previous frame is back, so playback never queues.
    if (!inFlight && now - lastTick >= dt) {
      lastTick = now;
      const next = state.time + 1 > scene.end ? scene.start : state.time + 1;
      setTime(next);
    }
    requestAnimationFrame(tick);
  }

  for (const [id, key] of [['show-proxy', 'showProxy'], ['view-drives', 'viewDrives'], ['show-bake', 'showBake']]) {
    $(id).addEventListener('change', (e) => {
      state[key] = e.target.checked;
      request();
    });
  }

  // ---------- render button ----------
  $('render-button').addEventListener('click', async () => {
    const b = $('render-button');
    b.disabled = true;
    const started = performance.now();
    // Open the render pane first: the live view then takes its half, and the
    // render is made at that size, so the two show the same framing.
    const figure = $('render-figure');
    const wasHidden = figure.hidden;
    figure.hidden = false;
    draw();
    const w = Math.min(1280, Math.max(16, canvas.clientWidth));
    const h = Math.min(1280, Math.max(16, canvas.clientHeight));
    try {
      const r = await fetch('api/render', {
        method: 'POST',
        headers: { 'Content-Type': 'application/json' },
        // The frame shown: with "show bake" ticked, the bake is rendered.
        body: JSON.stringify({ frame: { ...frameRequest(), proxy: false }, camera: cameraPose(w / h), width: w, height: h }),
      });
      if (!r.ok) throw new Error((await r.json()).error || r.statusText);
      const blob = await r.blob();
      const img = $('render');
      if (img.src) URL.revokeObjectURL(img.src);
      img.src = URL.createObjectURL(blob);
      const source = state.showBake ? ' · bake' : '';
      $('render-caption').textContent = `painterly render${source} · t=${state.time} · ${w}×${h} · ${(performance.now() - started).toFixed(0)} ms`;
      api.rendered = (api.rendered || 0) + 1;
      draw();
    } catch (e) {
      if (wasHidden && !$('render').src) {
        figure.hidden = true;
        draw();
      }
      fail(`render: ${e.message}`);
    } finally {
      b.disabled = false;
    }
  });

  // ---------- start ----------
  async function start() {
    const [sceneRes, strokesRes] = await Promise.all([fetch('api/scene'), fetch('api/strokes')]);
    if (!sceneRes.ok || !strokesRes.ok) throw new Error('cannot load the scene from the preview server');
    scene = await sceneRes.json();
    api.scene = scene;
    const statics = decode(await strokesRes.arrayBuffer());
    $('file').textContent = scene.file;
    document.title = `painterly preview: ${short(scene.file)}`;
    scene.layers.forEach((info, i) => {
      layers.push(makeLayer(info, statics.arrays[`layer/${i}/widths`], statics.arrays[`layer/${i}/colors`]));
    });
    for (const v of scene.views) views.push(makeMesh(v));
    for (const p of scene.proxies) proxies.push(makeMesh(p));
    setOrbitFrom(scene.view.position, scene.view.target, scene.view.up);
    orbit.fovY = scene.view.fov_y;
    orbit.aspect = scene.view.aspect;
    timeInput.min = scene.start;
    timeInput.max = scene.end;
    $('bake-toggle').hidden = !scene.bake;
    buildAxes();
    buildLayers();
    buildProblems();
    socket = await openSocket();
    setTime(scene.start);
    api.ready = true;
  }
  api.layers = layers;
  api.views = views;
  api.idle = () => api.ready && !inFlight && !dirty;
  api.layerPoints = (i) => (frame && frame.arrays[`layer/${i}/points`] ? Array.from(frame.arrays[`layer/${i}/points`]) : null);
  api.layerOpacity = (i) => (frame && frame.arrays[`layer/${i}/opacity`] ? Array.from(frame.arrays[`layer/${i}/opacity`]) : null);
  api.viewPoints = (i) => (frame && frame.arrays[`view/${i}/points`] ? Array.from(frame.arrays[`view/${i}/points`]) : null);
  start().catch((e) => fail(e.message));
})();
