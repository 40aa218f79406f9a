// Live view: binary frames from the server, interpolated at the browser's frame rate.
import { drawBodies, drawCorridors, drawFloor, layoutImage, statusOf, downloadCanvas } from './view.js';

const SPEEDS = [1, 2, 4, 8, 16, 32, 64, 200, 0]; // ticks per second; 0 = as fast as it runs
const NO_NODE = 0xFFFFFFFF;

function parseFrame(buf) {
  const dv = new DataView(buf);
  const n = dv.getUint32(16, true), H = dv.getUint16(20, true);
  const f = {
    tick: dv.getUint32(4, true), time: dv.getFloat32(8, true), tickS: dv.getFloat32(12, true),
    n, H, rate: dv.getFloat32(24, true),
  };
  let o = 36;
  f.x = new Float32Array(buf, o, n); o += 4 * n;
  f.y = new Float32Array(buf, o, n); o += 4 * n;
  f.h = new Float32Array(buf, o, n); o += 4 * n;
  f.state = new Uint8Array(buf, o, n); o += n;
  f.loaded = new Uint8Array(buf, o, n); o += n;
  o += (4 - (2 * n) % 4) % 4;
  f.paths = new Uint32Array(buf, o, n * H);
  f.status = new Uint8Array(n);
  for (let i = 0; i < n; i++) f.status[i] = statusOf(f.state[i], f.loaded[i]);
  return f;
}

export class Live {
  constructor(canvas, cam, sock) {
    this.canvas = canvas; this.cam = cam; this.sock = sock; this.ctx = canvas.getContext('2d');
    this.scene = null; this.prev = null; this.cur = null; this.status = null; this.selected = null;
    this.interval = 250; this.arrived = 0; this.hover = null; this.info = null;
    this.ix = this.iy = this.ih = null;
    const $ = (id) => document.getElementById(id);
    this.$ = $;
    $('b-pause').onclick = () => this.sock.send({ type: this.status && this.status.paused ? 'resume' : 'pause' });
    $('b-step').onclick = () => this.sock.send({ type: 'step', count: 1 });
    $('speed').oninput = () => {
      const v = SPEEDS[+$('speed').value];
      $('speed-v').textContent = v ? `${v} t/s` : 'max';
      this.sock.send({ type: 'speed', ticks_per_s: v });
    };
    $('b-orders').onclick = () => this.sock.send({ type: 'add_orders', count: Math.max(1, Math.min(1000, +$('n-orders').value || 1)) });
    $('b-restart').onclick = () => {
      const m = { type: 'restart', executor: $('executor').value };
      if ($('seed').value !== '') m.seed = +$('seed').value;
      this.sock.send(m);
    };
    $('b-fail').onclick = () => this.selected !== null && this.sock.send({ type: 'fail', agv: this.selected });
    $('b-repair').onclick = () => this.selected !== null && this.sock.send({ type: 'repair', agv: this.selected });
    $('b-png').onclick = () => downloadCanvas(canvas, `warerover-live-t${this.cur ? this.cur.tick : 0}.png`);
    $('b-glb-layout').onclick = () => this.sock.send({ type: 'export_glb', what: 'layout', path: 'exports/layout.glb' });
    $('b-glb-ep').onclick = () => this.sock.send({ type: 'export_glb', what: 'episode', path: 'exports/episode.glb' });
    canvas.addEventListener('mousemove', (e) => { if (this.active) this.onHover(e); });
    canvas.addEventListener('mouseleave', () => { this.hover = null; $('tooltip').hidden = true; });
    canvas.addEventListener('click', (e) => { if (this.active && !cam.lastDragMoved) this.onClick(e); });
    this.tpCanvas = $('tp-plot');
    setInterval(() => this.refreshInfo(), 500);
  }
  activate() { this.cam.panButtons = [0, 1, 2]; this.fitted = false; this.$('tooltip').hidden = true; }

  onMessage(msg) {
    if (msg.type === 'hello') { this.setScene(msg.scene); this.setStatus(msg.status); }
    else if (msg.type === 'scene') this.setScene(msg);
    else if (msg.type === 'status') this.setStatus(msg);
    else if (msg.type === 'agv') { this.info = msg; this.showInfo(); }
    else if (msg.type === 'ack' && (msg.of === 'pause' || msg.of === 'resume' || msg.of === 'step')) {
      this.setStatus({ ...(this.status || {}), paused: msg.paused });
    } else if (msg.type === 'exported') this.$('sel-info').textContent = `wrote ${msg.path} (${msg.bytes} bytes)`;
    else if (msg.type === 'error' && this.active) this.$('sel-info').textContent = `error: ${msg.error}`;
  }

  setScene(s) {
    this.scene = s;
    this.img = layoutImage(s.rows, s.cols, s.grid);
    this.body = new Float32Array(2 * s.agvs.length);
    this.k = new Uint8Array(s.agvs.length);
    s.agvs.forEach((a, i) => { this.body[2 * i] = a.body_m[0]; this.body[2 * i + 1] = a.body_m[1]; this.k[i] = a.k; });
    this.prev = this.cur = null; this.fitted = false;
    this.$('scene-name').textContent = `${s.name}: ${s.rows}x${s.cols} cells, ${s.agvs.length} AGVs, ${s.scheduler} + ${s.planner} on ${s.executor}, seed ${s.seed}`;
    this.$('executor').value = s.executor;
    window.wr.scene = s;
  }

  setStatus(st) {
    this.status = st;
    const $ = this.$;
    window.wr.status = st;
    if (st.tick !== undefined) {
      $('c-tick').textContent = st.tick; $('c-time').textContent = `${st.time_s.toFixed(0)} s`;
      $('c-orders').textContent = `${st.orders_done} / ${st.orders_total}`;
      $('c-pending').textContent = st.orders_pending; $('c-tp').textContent = st.throughput.toFixed(3);
      $('c-failed').textContent = st.failed.length;
      $('c-rate').textContent = `${st.sim_ticks_per_s.toFixed(0)} t/s`;
      this.plot(st.tp_points || []);
    }
    if (st.ticks_per_s !== undefined && document.activeElement !== $('speed')) {
      let best = 0;
      SPEEDS.forEach((v, i) => { if (Math.abs(v - st.ticks_per_s) < Math.abs(SPEEDS[best] - st.ticks_per_s)) best = i; });
      $('speed').value = best; $('speed-v').textContent = SPEEDS[best] ? `${SPEEDS[best]} t/s` : 'max';
    }
    $('b-pause').textContent = st.paused ? 'Resume' : 'Pause';
    $('b-pause').classList.toggle('on', !!st.paused);
    window.wr.paused = st.paused;
  }

  onFrame(buf) {
    const f = parseFrame(buf);
    const now = performance.now();
    if (this.cur && this.cur.n === f.n && f.tick !== this.cur.tick) {
      this.interval = Math.min(2000, Math.max(16, 0.7 * this.interval + 0.3 * (now - this.arrived)));
      this.prev = this.cur;
    } else if (!this.cur || this.cur.n !== f.n) this.prev = null;
    this.cur = f; this.arrived = now;
    window.wr.frames++; window.wr.tick = f.tick;
  }

  plot(points) {
    const c = this.tpCanvas, ctx = c.getContext('2d');
    ctx.clearRect(0, 0, c.width, c.height);
    if (points.length < 2) return;
    const tMax = Math.max(1, points[points.length - 1][0]), dMax = Math.max(1, ...points.map((p) => p[1]));
    ctx.strokeStyle = '#ccc'; ctx.strokeRect(0.5, 0.5, c.width - 1, c.height - 1);
    ctx.beginPath();
    points.forEach(([t, d], i) => {
      const x = 4 + (c.width - 8) * t / tMax, y = c.height - 4 - (c.height - 16) * d / dMax;
      i ? ctx.lineTo(x, y) : ctx.moveTo(x, y);
    });
    ctx.strokeStyle = '#0072B2'; ctx.lineWidth = 1.5; ctx.stroke();
    ctx.fillStyle = '#555'; ctx.font = '10px system-ui';
    ctx.fillText(`orders done: ${dMax}  (tick ${tMax})`, 6, 11);
  }

  positions(now) {
    const f = this.cur, p = this.prev, n = f.n;
    if (!this.ix || this.ix.length !== n) { this.ix = new Float32Array(n); this.iy = new Float32Array(n); this.ih = new Float32Array(n); }
    const a = p ? Math.min(1, (now - this.arrived) / this.interval) : 1;
    for (let i = 0; i < n; i++) {
      if (a >= 1) { this.ix[i] = f.x[i]; this.iy[i] = f.y[i]; this.ih[i] = f.h[i]; continue; }
      this.ix[i] = p.x[i] + a * (f.x[i] - p.x[i]);
      this.iy[i] = p.y[i] + a * (f.y[i] - p.y[i]);
      let dh = f.h[i] - p.h[i];
      dh = ((dh + Math.PI) % (2 * Math.PI) + 2 * Math.PI) % (2 * Math.PI) - Math.PI;
      this.ih[i] = p.h[i] + a * dh;
    }
  }

  draw(now) {
    const ctx = this.ctx, s = this.scene;
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.clearRect(0, 0, this.canvas.width, this.canvas.height);
    if (!s) return;
    const cell = s.cell_m;
    if (!this.fitted && this.canvas.clientWidth > 0) { this.cam.fit(s.cols * cell, s.rows * cell); this.fitted = true; }
    this.cam.apply(ctx);
    drawFloor(ctx, this.cam, this.img, s.rows, s.cols, cell, { shelves: s.shelves, access: s.access_points });
    if (this.status) drawCorridors(ctx, this.cam, this.status.corridors);
    const f = this.cur;
    if (!f) return;
    this.positions(now);
    if (this.$('show-paths').checked && f.H > 0) this.drawPaths(ctx, f);
    drawBodies(ctx, this.cam, f.n, this.ix, this.iy, this.ih, f.status, this.body);
    if (this.selected !== null && this.selected < f.n) {
      const i = this.selected;
      ctx.beginPath(); ctx.arc(this.ix[i], this.iy[i], Math.max(this.body[2 * i], 6 / this.cam.scale) * 0.9, 0, 2 * Math.PI);
      ctx.strokeStyle = '#000'; ctx.lineWidth = 2 / this.cam.scale; ctx.stroke();
    }
    const st = this.status || {};
    document.getElementById('hud').textContent =
      `t = ${f.time.toFixed(0)} s  ·  tick ${f.tick}  ·  orders ${st.orders_done ?? 0}/${st.orders_total ?? 0}  ·  ${st.paused ? 'paused' : st.done ? 'done' : 'running'}`;
  }

  drawPaths(ctx, f) {
    const s = this.scene, cols = s.cols, cell = s.cell_m, H = f.H;
    const path = new Path2D();
    for (let i = 0; i < f.n; i++) {
      if (f.paths[i * H] === NO_NODE) continue;
      const k = this.k[i];
      path.moveTo(this.ix[i], this.iy[i]);
      for (let j = 0; j < H; j++) {
        const node = f.paths[i * H + j];
        if (node === NO_NODE) break;
        const r = Math.floor(node / cols), c = node - r * cols;
        path.lineTo((c + k / 2) * cell, (r + k / 2) * cell);
      }
    }
    ctx.strokeStyle = 'rgba(0,114,178,0.45)'; ctx.lineWidth = Math.max(1.5 / this.cam.scale, 0.06); ctx.stroke(path);
  }

  agvAt(e) {
    const f = this.cur; if (!f || !this.ix) return null;
    const r = this.canvas.getBoundingClientRect();
    const [x, y] = this.cam.toWorld(e.clientX - r.left, e.clientY - r.top);
    let best = null, bd = Infinity;
    for (let i = 0; i < f.n; i++) {
      const d = (this.ix[i] - x) ** 2 + (this.iy[i] - y) ** 2;
      if (d < bd) { bd = d; best = i; }
    }
    const reach = Math.max(this.body[2 * best] * 0.75, 8 / this.cam.scale);
    return bd <= reach * reach ? best : null;
  }

  onHover(e) {
    const i = this.agvAt(e), tip = this.$('tooltip');
    if (i === null) { tip.hidden = true; this.hover = null; return; }
    const r = this.canvas.getBoundingClientRect();
    tip.style.left = `${e.clientX - r.left + 14}px`; tip.style.top = `${e.clientY - r.top + 10}px`;
    if (this.hover !== i) { this.hover = i; this.sock.send({ type: 'inspect', agv: i }); }
    tip.hidden = false;
    this.showInfo();
  }

  onClick(e) {
    const i = this.agvAt(e);
    this.selected = i;
    window.wr.selected = i;
    this.$('sel-id').textContent = i === null ? '—' : String(i);
    if (i !== null) this.sock.send({ type: 'inspect', agv: i });
    this.showInfo();
  }

  refreshInfo() {
    if (!this.active) return;
    const i = this.hover !== null ? this.hover : this.selected;
    if (i !== null) this.sock.send({ type: 'inspect', agv: i });
  }

  showInfo() {
    const m = this.info, $ = this.$;
    const failed = this.cur && this.selected !== null ? this.cur.state[this.selected] === 7 : false;
    $('b-fail').disabled = this.selected === null || failed;
    $('b-repair').disabled = this.selected === null || !failed;
    if (!m) return;
    const trip = m.trip ? `trip ${m.trip.id}: shelf ${m.trip.shelf}, orders ${m.trip.orders.join(',')}` : 'no trip';
    const text = `AGV ${m.id} (${m.type}, ${m.k}x${m.k})\n${m.state}${m.loaded ? ', loaded' : ''}\n` +
      `cell ${m.cell} → ${m.goal ?? '—'}\nspeed ${m.speed_mps} m/s\n${trip}\n` +
      `waiting for: ${m.waiting_for.length ? m.waiting_for.join(', ') : 'nobody'}`;
    if (m.id === this.hover) $('tooltip').textContent = text;
    if (m.id === this.selected) $('sel-info').textContent = text;
  }
}
