// Entry point: the socket, the tabs, and window.wr (state for tests and the benchmark).
import { Live } from './live.js';
import { Editor } from './editor.js';
import { Replay } from './replay.js';
import { View3D } from './view3d.js';
import { Camera, fitCanvas } from './view.js';

const canvas = document.getElementById('view');
const wr = window.wr = { rafFrames: 0, frames: 0, tick: 0, mode: 'live', errors: [] };

class Socket {
  constructor(onMessage, onBinary) {
    this.onMessage = onMessage; this.onBinary = onBinary; this.nextId = 1; this.pending = new Map();
    this.connect();
  }
  connect() {
    const ws = this.ws = new WebSocket(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws`);
    ws.binaryType = 'arraybuffer';
    const conn = document.getElementById('conn');
    ws.onopen = () => { conn.textContent = 'connected'; conn.className = 'conn ok'; wr.connected = true; };
    ws.onclose = () => { conn.textContent = 'disconnected — retrying'; conn.className = 'conn'; wr.connected = false; setTimeout(() => this.connect(), 1000); };
    ws.onmessage = (e) => {
      if (typeof e.data !== 'string') { this.onBinary(e.data); return; }
      const msg = JSON.parse(e.data);
      if (msg.type === 'error') { wr.errors.push(msg.error); console.warn('server:', msg.error); }
      if (msg.id !== undefined && this.pending.has(msg.id)) {
        const { resolve, keep } = this.pending.get(msg.id);
        if (!keep) this.pending.delete(msg.id);
        resolve(msg);
      }
      this.onMessage(msg);
    };
  }
  send(msg) { if (this.ws.readyState === 1) this.ws.send(JSON.stringify(msg)); }
  request(msg) {
    const id = this.nextId++;
    return new Promise((resolve) => { this.pending.set(id, { resolve }); this.send({ ...msg, id }); });
  }
}

const cam = new Camera(canvas, () => { wr.dirty = true; });
const views = {};
const sock = new Socket((msg) => {
  for (const v of Object.values(views)) v.onMessage(msg);
}, (buf) => {
  const magic = new DataView(buf).getUint32(0, true);
  if (magic === 0x31465257) views.live.onFrame(buf);
  else if (magic === 0x31525257) views.replay.onData(buf);
});
wr.sock = sock; wr.request = (m) => sock.request(m); wr.cam = cam;
views.live = new Live(canvas, cam, sock);
views.editor = new Editor(canvas, cam, sock);
views.replay = new Replay(canvas, cam, sock);
const canvas3d = document.getElementById('view3d');
views['3d'] = new View3D(canvas3d, views.live);
wr.views = views;

function setTab(name) {
  wr.mode = name;
  document.querySelectorAll('#tabs button').forEach((b) => b.classList.toggle('on', b.dataset.tab === name));
  const panel = name === '3d' ? 'live' : name;
  document.querySelectorAll('aside section').forEach((s) => { s.hidden = s.dataset.panel !== panel; });
  canvas.hidden = name === '3d'; canvas3d.hidden = name !== '3d';
  for (const [k, v] of Object.entries(views)) v.active = k === name;
  views[name].activate();
}
document.querySelectorAll('#tabs button').forEach((b) => b.addEventListener('click', () => setTab(b.dataset.tab)));
wr.setTab = setTab;
setTab('live');

// Keys in the live and 3D views: space pauses / resumes, n steps one tick, f fails and
// r repairs the selected AGV.
window.addEventListener('keydown', (e) => {
  if (e.target.closest('input, select, textarea') || (wr.mode !== 'live' && wr.mode !== '3d')) return;
  const live = views.live, sel = live.selected;
  if (e.key === ' ') { e.preventDefault(); sock.send({ type: live.status && live.status.paused ? 'resume' : 'pause' }); }
  else if (e.key === 'n') sock.send({ type: 'step', count: 1 });
  else if (e.key === 'f' && sel !== null) sock.send({ type: 'fail', agv: sel });
  else if (e.key === 'r' && sel !== null) sock.send({ type: 'repair', agv: sel });
});

let fpsT0 = performance.now(), fpsN = 0;
function loop(now) {
  wr.rafFrames++; fpsN++;
  if (now - fpsT0 >= 1000) {
    wr.fps = fpsN * 1000 / (now - fpsT0); fpsT0 = now; fpsN = 0;
    document.getElementById('c-fps').textContent = `${wr.fps.toFixed(0)} fps`;
  }
  fitCanvas(wr.mode === '3d' ? canvas3d : canvas);
  views[wr.mode].draw(now);
  requestAnimationFrame(loop);
}
requestAnimationFrame(loop);
