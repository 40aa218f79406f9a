// 3D view of the live scene: WebGL2, no library. Unit cubes drawn instanced: the layout
// (obstacles, shelves, stations, parking) once, the AGVs every frame from the live view's
// interpolated poses. Drag orbits, wheel zooms. Y up; map x -> X, map y -> Z.
const CELL = { 1: [0.25, 0.25, 0.25, 1.0], 2: [0.55, 0.77, 0.93, 1.6], 3: [0.45, 0.78, 0.68, 0.3], 4: [0.96, 0.94, 0.64, 0.02] };
const STATUS = [[0.6, 0.6, 0.6], [0, 0.447, 0.698], [0.902, 0.624, 0], [0.835, 0.369, 0]];

const VS = `#version 300 es
layout(location=0) in vec3 pos; layout(location=1) in vec3 nrm;
layout(location=2) in vec3 at; layout(location=3) in vec3 size; layout(location=4) in float yaw;
layout(location=5) in vec3 col;
uniform mat4 mvp; out vec3 vcol;
void main() {
  float c = cos(yaw), s = sin(yaw);
  vec3 p = pos * size; p = vec3(c * p.x - s * p.z, p.y, s * p.x + c * p.z);
  vec3 n = vec3(c * nrm.x - s * nrm.z, nrm.y, s * nrm.x + c * nrm.z);
  float light = 0.45 + 0.55 * max(dot(n, normalize(vec3(0.4, 1.0, 0.3))), 0.0);
  vcol = col * light; gl_Position = mvp * vec4(p + at, 1.0);
}`;
const FS = `#version 300 es
precision mediump float; in vec3 vcol; out vec4 o; void main() { o = vec4(vcol, 1.0); }`;

function cube() {  // 36 vertices: position (centred on x/z, base at y = 0) and normal
  const f = [[[1, 0, 0], [0, 0, -1], [0, 1, 0]], [[-1, 0, 0], [0, 0, 1], [0, 1, 0]], [[0, 1, 0], [1, 0, 0], [0, 0, -1]],
    [[0, -1, 0], [1, 0, 0], [0, 0, 1]], [[0, 0, 1], [1, 0, 0], [0, 1, 0]], [[0, 0, -1], [-1, 0, 0], [0, 1, 0]]];
  const out = [];
  for (const [n, u, v] of f) {
    const corner = (a, b) => [0, 1, 2].map((i) => 0.5 * n[i] + 0.5 * a * u[i] + 0.5 * b * v[i]);
    for (const [a, b] of [[-1, -1], [1, -1], [1, 1], [-1, -1], [1, 1], [-1, 1]]) {
      const p = corner(a, b);
      out.push(p[0], p[1] + 0.5, p[2], ...n);
    }
  }
  return new Float32Array(out);
}

function mul(a, b) {
  const o = new Float32Array(16);
  for (let i = 0; i < 4; i++) for (let j = 0; j < 4; j++) {
    let s = 0; for (let k = 0; k < 4; k++) s += a[k * 4 + j] * b[i * 4 + k]; o[i * 4 + j] = s;
  }
  return o;
}
function perspective(fov, aspect, near, far) {
  const f = 1 / Math.tan(fov / 2), nf = 1 / (near - far);
  return new Float32Array([f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0]);
}
function lookAt(e, c, up) {
  const z = [e[0] - c[0], e[1] - c[1], e[2] - c[2]], zl = Math.hypot(...z); z.forEach((v, i) => { z[i] = v / zl; });
  const x = [up[1] * z[2] - up[2] * z[1], up[2] * z[0] - up[0] * z[2], up[0] * z[1] - up[1] * z[0]];
  const xl = Math.hypot(...x); x.forEach((v, i) => { x[i] = v / xl; });
  const y = [z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]];
  const d = (a) => -(a[0] * e[0] + a[1] * e[1] + a[2] * e[2]);
  return new Float32Array([x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0, d(x), d(y), d(z), 1]);
}

export class View3D {
  constructor(canvas, live) {
    this.canvas = canvas; this.live = live; this.yaw = 0.6; this.pitch = 0.9; this.dist = null;
    const gl = this.gl = canvas.getContext('webgl2', { antialias: true, preserveDrawingBuffer: true });
    if (!gl) return;
    const sh = (type, src) => { const s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s); return s; };
    const p = this.prog = gl.createProgram();
    gl.attachShader(p, sh(gl.VERTEX_SHADER, VS)); gl.attachShader(p, sh(gl.FRAGMENT_SHADER, FS)); gl.linkProgram(p);
    this.uMvp = gl.getUniformLocation(p, 'mvp');
    this.mesh = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, this.mesh); gl.bufferData(gl.ARRAY_BUFFER, cube(), gl.STATIC_DRAW);
    this.staticVao = this.vao(this.staticBuf = gl.createBuffer());
    this.agvVao = this.vao(this.agvBuf = gl.createBuffer());
    let drag = null;
    canvas.addEventListener('mousedown', (e) => { drag = [e.clientX, e.clientY, this.yaw, this.pitch]; });
    window.addEventListener('mouseup', () => { drag = null; });
    window.addEventListener('mousemove', (e) => {
      if (!drag) return;
      this.yaw = drag[2] - (e.clientX - drag[0]) * 0.01;
      this.pitch = Math.min(1.5, Math.max(0.1, drag[3] + (e.clientY - drag[1]) * 0.01));
    });
    canvas.addEventListener('wheel', (e) => { e.preventDefault(); this.dist *= Math.exp(e.deltaY * 0.001); }, { passive: false });
  }
  vao(buf) {
    const gl = this.gl, v = gl.createVertexArray();
    gl.bindVertexArray(v);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.mesh);
    gl.enableVertexAttribArray(0); gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 24, 0);
    gl.enableVertexAttribArray(1); gl.vertexAttribPointer(1, 3, gl.FLOAT, false, 24, 12);
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    [[2, 3, 0], [3, 3, 12], [4, 1, 24], [5, 3, 28]].forEach(([loc, n, off]) => {
      gl.enableVertexAttribArray(loc); gl.vertexAttribPointer(loc, n, gl.FLOAT, false, 40, off); gl.vertexAttribDivisor(loc, 1);
    });
    gl.bindVertexArray(null);
    return v;
  }
  buildScene(s) {
    const inst = [], cell = s.cell_m;
    const push = (x, y, z, sx, sy, sz, yaw, c) => inst.push(x, y, z, sx, sy, sz, yaw, c[0], c[1], c[2]);
    push(s.cols * cell / 2, -0.02, s.rows * cell / 2, s.cols * cell, 0.02, s.rows * cell, 0, [0.93, 0.93, 0.93]);
    const big = new Set();
    for (const [r, c, k] of s.shelves) if (k > 1) {
      for (let i = 0; i < k; i++) for (let j = 0; j < k; j++) big.add((r + i) * s.cols + c + j);
      push((c + k / 2) * cell, 0, (r + k / 2) * cell, k * cell * 0.92, CELL[2][3], k * cell * 0.92, 0, CELL[2]);
    }
    for (let i = 0; i < s.rows * s.cols; i++) {
      const v = s.grid.charCodeAt(i) - 48;
      if (!CELL[v] || big.has(i)) continue;
      const r = Math.floor(i / s.cols), c = i % s.cols, w = v === 1 ? 1 : 0.92;
      push((c + 0.5) * cell, 0, (r + 0.5) * cell, w * cell, CELL[v][3], w * cell, 0, CELL[v]);
    }
    const gl = this.gl;
    gl.bindBuffer(gl.ARRAY_BUFFER, this.staticBuf); gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(inst), gl.STATIC_DRAW);
    this.staticCount = inst.length / 10; this.scene = s;
    this.dist = Math.max(s.rows, s.cols) * cell * 1.3;
  }
  activate() {}
  onMessage() {}
  draw(now) {
    const gl = this.gl, live = this.live, s = live.scene;
    if (!gl || !s) return;
    if (this.scene !== s) this.buildScene(s);
    const w = this.canvas.width, h = this.canvas.height;
    gl.viewport(0, 0, w, h); gl.clearColor(1, 1, 1, 1); gl.enable(gl.DEPTH_TEST);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    const cx = s.cols * s.cell_m / 2, cz = s.rows * s.cell_m / 2, d = this.dist;
    const eye = [cx + d * Math.cos(this.pitch) * Math.sin(this.yaw), d * Math.sin(this.pitch), cz + d * Math.cos(this.pitch) * Math.cos(this.yaw)];
    const mvp = mul(perspective(0.8, w / h, 0.1, d * 4), lookAt(eye, [cx, 0, cz], [0, 1, 0]));
    gl.useProgram(this.prog); gl.uniformMatrix4fv(this.uMvp, false, mvp);
    gl.bindVertexArray(this.staticVao); gl.drawArraysInstanced(gl.TRIANGLES, 0, 36, this.staticCount);
    const f = live.cur;
    const cors = (live.status && live.status.corridors) || [];
    const ncells = cors.reduce((n, c) => n + c.cells.length, 0), nagv = f ? f.n : 0;
    if (nagv + ncells > 0) {
      const a = new Float32Array(10 * (nagv + ncells));
      let o = 0;
      if (f) {
        live.positions(now);
        for (let i = 0; i < f.n; i++, o += 10) {
          const c = STATUS[f.status[i]];
          a[o] = live.ix[i]; a[o + 1] = 0; a[o + 2] = live.iy[i];
          a[o + 3] = live.body[2 * i]; a[o + 4] = 0.45; a[o + 5] = live.body[2 * i + 1]; a[o + 6] = live.ih[i];
          a[o + 7] = c[0]; a[o + 8] = c[1]; a[o + 9] = c[2];
        }
      }
      for (const cor of cors) for (const cellIdx of cor.cells) {     // corridor cells: flat, purple
        const r = Math.floor(cellIdx / s.cols), c = cellIdx % s.cols;
        a.set([(c + 0.5) * s.cell_m, 0, (r + 0.5) * s.cell_m, s.cell_m, 0.04, s.cell_m, 0, 0.8, 0.475, 0.655], o);
        o += 10;
      }
      gl.bindBuffer(gl.ARRAY_BUFFER, this.agvBuf); gl.bufferData(gl.ARRAY_BUFFER, a, gl.DYNAMIC_DRAW);
      gl.bindVertexArray(this.agvVao); gl.drawArraysInstanced(gl.TRIANGLES, 0, 36, nagv + ncells);
    }
    gl.bindVertexArray(null);
    document.getElementById('hud').textContent = `3D · tick ${f ? f.tick : 0} · drag: orbit · wheel: zoom`;
  }
}
