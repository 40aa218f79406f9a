// Replay: a recorded run sent once by the server, scrubbed and played in the page.
import { drawBodies, drawCorridors, drawFloor, layoutImage, statusOf, downloadCanvas } from './view.js';

export class Replay {
  constructor(canvas, cam, sock) {
    this.canvas = canvas; this.cam = cam; this.sock = sock; this.ctx = canvas.getContext('2d');
    this.head = null; this.data = null; this.time = 0; this.playing = false; this.last = null;
    const $ = (id) => document.getElementById(id);
    this.$ = $;
    $('r-open').onclick = () => {
      const m = { type: 'replay_open', path: $('r-path').value };
      if ($('r-map').value) m.map = $('r-map').value;
      $('r-info').textContent = 'loading…';
      this.sock.send(m);
    };
    $('r-play').onclick = () => { this.setPlaying(!this.playing); };
    $('r-time').oninput = () => { this.time = +$('r-time').value; this.setPlaying(false); };
    $('r-png').onclick = () => downloadCanvas(canvas, `warerover-replay-${this.time.toFixed(1)}s.png`);
  }
  activate() {
    this.cam.panButtons = [0, 1, 2]; this.fitted = false;
    this.sock.send({ type: 'list_files', suffixes: ['.npz', '.json'], id: 'run-list' });
  }
  setPlaying(p) {
    this.playing = p && !!this.data; this.last = null;
    if (this.playing && this.head && this.time >= this.head.end_s) this.time = this.head.start_s;
    this.$('r-play').textContent = this.playing ? 'Pause' : 'Play';
  }
  onMessage(msg) {
    if (msg.type === 'replay') { this.head = msg; this.data = null; }
    else if (msg.type === 'error' && this.active) this.$('r-info').textContent = `error: ${msg.error}`;
    else if (msg.type === 'files' && msg.id === 'run-list') {
      this.$('run-files').innerHTML = msg.files.map((f) => `<option value="${f.replace(/"/g, '&quot;')}">`).join('');
    }
  }
  onData(buf) {
    const h = this.head, dv = new DataView(buf);
    const T = dv.getUint32(4, true), N = dv.getUint32(8, true), flags = dv.getUint32(12, true);
    let o = 16;
    const d = { T, N };
    d.t = new Float32Array(buf, o, T); o += 4 * T;
    for (const k of ['x', 'y', 'h']) { d[k] = new Float32Array(buf, o, T * N); o += 4 * T * N; }
    d.state = new Uint8Array(buf, o, T * N); o += T * N;
    d.loaded = new Uint8Array(buf, o, T * N); o += T * N;
    o += (4 - (2 * T * N) % 4) % 4;
    if (flags & 1) { d.gx = new Float32Array(buf, o, T * N); o += 4 * T * N; d.gy = new Float32Array(buf, o, T * N); }
    this.data = d;
    this.img = layoutImage(h.rows, h.cols, h.grid);
    this.body = new Float32Array(2 * N);
    h.body_m.forEach((b, i) => { this.body[2 * i] = b[0]; this.body[2 * i + 1] = b[1]; });
    this.bx = new Float32Array(N); this.by = new Float32Array(N); this.bh = new Float32Array(N);
    this.gx = new Float32Array(N); this.gy = new Float32Array(N); this.st = new Uint8Array(N);
    this.time = h.start_s; this.fitted = false;
    const r = this.$('r-time');
    r.min = h.start_s; r.max = h.end_s; r.step = Math.max(0.01, (h.end_s - h.start_s) / 2000); r.value = h.start_s;
    this.$('r-info').textContent = `${h.source} (${h.kind}): ${N} AGVs, ${T} samples, ${(h.end_s - h.start_s).toFixed(0)} s${h.ghosts ? ', with plans' : ''}`;
    window.wr.replay = { samples: T, agvs: N, end: h.end_s, start: h.start_s, time: this.time };
  }
  sample() {
    const d = this.data, N = d.N, t = d.t;
    let lo = 0, hi = d.T - 1;
    const q = Math.min(Math.max(this.time, t[0]), t[d.T - 1]);
    while (hi - lo > 1) { const m = (lo + hi) >> 1; if (t[m] <= q) lo = m; else hi = m; }
    if (d.T === 1) hi = 0;
    const w = hi === lo || t[hi] === t[lo] ? 0 : Math.min(1, (q - t[lo]) / (t[hi] - t[lo]));
    const a = lo * N, b = hi * N, k = w >= 1 ? b : a;
    for (let i = 0; i < N; i++) {
      this.bx[i] = d.x[a + i] + w * (d.x[b + i] - d.x[a + i]);
      this.by[i] = d.y[a + i] + w * (d.y[b + i] - d.y[a + i]);
      let dh = d.h[b + i] - d.h[a + i];
      dh = ((dh + Math.PI) % (2 * Math.PI) + 2 * Math.PI) % (2 * Math.PI) - Math.PI;
      this.bh[i] = d.h[a + i] + w * dh;
      this.st[i] = statusOf(d.state[k + i], d.loaded[k + i]);
      if (d.gx) { this.gx[i] = d.gx[a + i] + w * (d.gx[b + i] - d.gx[a + i]); this.gy[i] = d.gy[a + i] + w * (d.gy[b + i] - d.gy[a + i]); }
    }
  }
  draw(now) {
    const ctx = this.ctx, h = this.head, d = this.data;
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.clearRect(0, 0, this.canvas.width, this.canvas.height);
    if (!h || !d) { document.getElementById('hud').textContent = 'replay · open a run'; return; }
    if (this.playing) {
      if (this.last !== null) this.time += (now - this.last) / 1000 * +this.$('r-speed').value;
      this.last = now;
      if (this.time >= h.end_s) { this.time = h.end_s; this.setPlaying(false); }
      this.$('r-time').value = this.time;
    }
    const cell = h.cell_m;
    if (!this.fitted && this.canvas.clientWidth > 0) { this.cam.fit(h.cols * cell, h.rows * cell); this.fitted = true; }
    this.cam.apply(ctx);
    drawFloor(ctx, this.cam, this.img, h.rows, h.cols, cell);
    const tick = this.time / h.tick_s;
    drawCorridors(ctx, this.cam, h.corridors.filter((c) => c.open_tick <= tick && (c.close_tick === null || tick < c.close_tick)));
    this.sample();
    if (d.gx && this.$('r-ghosts').checked) {
      drawBodies(ctx, this.cam, d.N, this.gx, this.gy, this.bh, this.st, this.body, { ghost: true, alpha: 0.8 });
      const lag = new Path2D();
      for (let i = 0; i < d.N; i++) if (Math.abs(this.gx[i] - this.bx[i]) + Math.abs(this.gy[i] - this.by[i]) > 0.05) { lag.moveTo(this.bx[i], this.by[i]); lag.lineTo(this.gx[i], this.gy[i]); }
      ctx.strokeStyle = 'rgba(213,94,0,0.7)'; ctx.lineWidth = 1.5 / this.cam.scale; ctx.stroke(lag);
    }
    drawBodies(ctx, this.cam, d.N, this.bx, this.by, this.bh, this.st, this.body);
    this.$('r-clock').textContent = `${this.time.toFixed(1)} / ${h.end_s.toFixed(1)} s (tick ${Math.floor(tick)})`;
    document.getElementById('hud').textContent = `replay · ${h.source} · t = ${this.time.toFixed(1)} s`;
    window.wr.replay.time = this.time;
    window.wr.replay.atEnd = this.time >= h.end_s - 1e-6;
  }
}
