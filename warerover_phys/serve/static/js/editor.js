// Layout editor: paint cells, load / save layout YAML, show `check` errors on their cells.
const COLORS = { '.': '#fafafa', '#': '#404040', S: '#a8d3f1', B: '#8cc3ea', R: '#73c7ae', P: '#f6f0a3', A: '#fafafa' };

export class Editor {
  constructor(canvas, cam, sock) {
    this.canvas = canvas; this.cam = cam; this.sock = sock; this.ctx = canvas.getContext('2d');
    this.tool = '.'; this.errors = []; this.painting = false;
    const $ = (id) => document.getElementById(id);
    this.$ = $;
    this.newGrid(15, 20);
    document.querySelectorAll('#tools button').forEach((b) => b.addEventListener('click', () => {
      this.tool = b.dataset.tool;
      document.querySelectorAll('#tools button').forEach((x) => x.classList.toggle('on', x === b));
    }));
    $('e-new').onclick = () => this.newGrid(+$('e-rows').value || 15, +$('e-cols').value || 20);
    $('e-load').onclick = () => this.sock.send({ type: 'layout_load', path: $('e-path').value });
    $('e-save').onclick = () => this.sock.send({ type: 'layout_save', path: $('e-path').value, layout: this.doc() });
    $('e-check').onclick = () => this.sock.send({ type: 'layout_check', layout: this.doc() });
    canvas.addEventListener('mousedown', (e) => {
      if (!this.active || e.button !== 0) return;
      this.painting = true; this.paintAt(e);
    });
    canvas.addEventListener('mousemove', (e) => { if (this.active && this.painting) this.paintAt(e); });
    window.addEventListener('mouseup', () => { this.painting = false; });
  }
  activate() {
    this.cam.panButtons = [1, 2]; this.fitted = false;
    this.sock.send({ type: 'list_files', suffixes: ['.yaml', '.yml', '.map'], id: 'yaml-list' });
  }
  newGrid(rows, cols) {
    rows = Math.max(3, Math.min(1000, rows)); cols = Math.max(3, Math.min(1000, cols));
    this.rows = rows; this.cols = cols; this.cell = 1.0;
    this.cells = new Array(rows * cols).fill('.');
    for (let r = 0; r < rows; r++) for (let c = 0; c < cols; c++)
      if (r === 0 || c === 0 || r === rows - 1 || c === cols - 1) this.cells[r * cols + c] = '.';
    this.big = []; this.errors = []; this.fitted = false; this.dirty = true; this.showErrors();
  }
  rebuild() {     // the cells as an image of one pixel per cell (redrawn only after a change)
    if (!this.img || this.img.width !== this.cols || this.img.height !== this.rows) {
      this.img = document.createElement('canvas'); this.img.width = this.cols; this.img.height = this.rows;
    }
    const ctx = this.img.getContext('2d'), data = ctx.createImageData(this.cols, this.rows);
    const rgb = {};
    for (const [ch, hex] of Object.entries(COLORS)) rgb[ch] = [1, 3, 5].map((i) => parseInt(hex.slice(i, i + 2), 16));
    this.access = [];
    this.cells.forEach((ch, i) => {
      const v = rgb[ch] || [255, 0, 255];
      data.data.set([v[0], v[1], v[2], 255], 4 * i);
      if (ch === 'A') this.access.push(i);
    });
    ctx.putImageData(data, 0, 0);
    this.dirty = false;
  }
  doc() {
    return { rows: this.rows, cols: this.cols, cell_m: this.cell, cells: this.cells.join(''), big_shelves: this.big };
  }
  load(doc) {
    this.rows = doc.rows; this.cols = doc.cols; this.cell = doc.cell_m;
    this.cells = doc.cells.split(''); this.big = doc.big_shelves.map((b) => [b[0], b[1]]);
    this.errors = []; this.fitted = false; this.dirty = true; this.showErrors();
    this.$('e-rows').value = doc.rows; this.$('e-cols').value = doc.cols;
  }
  removeBigAt(r, c) {
    const i = this.big.findIndex(([br, bc]) => r >= br && r < br + 2 && c >= bc && c < bc + 2);
    if (i < 0) return;
    const [br, bc] = this.big[i];
    this.big.splice(i, 1);
    for (let dr = 0; dr < 2; dr++) for (let dc = 0; dc < 2; dc++) this.cells[(br + dr) * this.cols + bc + dc] = '.';
    this.dirty = true;
  }
  set(r, c, ch) {
    if (r < 0 || c < 0 || r >= this.rows || c >= this.cols) return false;
    if (this.cells[r * this.cols + c] === 'B') this.removeBigAt(r, c);
    this.cells[r * this.cols + c] = ch;
    this.dirty = true;
    return true;
  }
  paintCell(r, c, tool) {
    if (tool === 'B') {
      if (r + 1 >= this.rows || c + 1 >= this.cols || r < 0 || c < 0) return;
      for (let dr = 0; dr < 2; dr++) for (let dc = 0; dc < 2; dc++) this.set(r + dr, c + dc, 'B');
      this.big.push([r, c]);
    } else this.set(r, c, tool);
  }
  paintAt(e) {
    const rect = this.canvas.getBoundingClientRect();
    const [x, y] = this.cam.toWorld(e.clientX - rect.left, e.clientY - rect.top);
    const r = Math.floor(y / this.cell), c = Math.floor(x / this.cell);
    if (r < 0 || c < 0 || r >= this.rows || c >= this.cols) return;
    const cur = this.cells[r * this.cols + c];
    if (this.tool === 'B' && cur === 'B') return;
    if (cur === this.tool && this.tool !== 'B') return;
    this.paintCell(r, c, this.tool);
  }
  onMessage(msg) {
    const $ = this.$;
    if (msg.type === 'layout') { this.load(msg.layout); $('e-result').textContent = `loaded ${msg.path}`; }
    else if (msg.type === 'check') { this.errors = msg.errors; this.showErrors(); $('e-result').textContent = msg.errors.length ? 'check: errors' : 'check: ok'; }
    else if (msg.type === 'saved') {
      this.errors = msg.errors; this.showErrors();
      $('e-result').textContent = `saved ${msg.files.join(', ')} — check ${msg.ok ? 'ok' : 'found errors'}`;
      window.wr.lastSave = msg;
    } else if (msg.type === 'files') {
      const list = msg.id === 'yaml-list' ? 'yaml-files' : 'run-files';
      $(list).innerHTML = msg.files.map((f) => `<option value="${f.replace(/"/g, '&quot;')}">`).join('');
    } else if (msg.type === 'error' && this.active) $('e-result').textContent = `error: ${msg.error}`;
  }
  showErrors() {
    const ul = this.$('e-errors');
    ul.innerHTML = '';
    for (const e of this.errors) {
      const li = document.createElement('li');
      li.textContent = e.message + (e.cells.length ? `  [cells ${e.cells.map((c) => `(${c})`).join(' ')}]` : '');
      ul.appendChild(li);
    }
  }
  draw() {
    const ctx = this.ctx, cell = this.cell, cam = this.cam;
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.clearRect(0, 0, this.canvas.width, this.canvas.height);
    if (!this.fitted && this.canvas.clientWidth > 0) { cam.fit(this.cols * cell, this.rows * cell); this.fitted = true; }
    cam.apply(ctx);
    if (this.dirty !== false || !this.img) this.rebuild();
    ctx.imageSmoothingEnabled = false;
    ctx.drawImage(this.img, 0, 0, this.cols * cell, this.rows * cell);
    if (cam.scale * cell >= 6) {
      ctx.beginPath();
      for (let r = 0; r <= this.rows; r++) { ctx.moveTo(0, r * cell); ctx.lineTo(this.cols * cell, r * cell); }
      for (let c = 0; c <= this.cols; c++) { ctx.moveTo(c * cell, 0); ctx.lineTo(c * cell, this.rows * cell); }
      ctx.strokeStyle = '#d4d4d4'; ctx.lineWidth = 1 / cam.scale; ctx.stroke();
    }
    ctx.strokeStyle = '#2f6f9f'; ctx.lineWidth = 2 / cam.scale;
    for (const [r, c] of this.big) ctx.strokeRect(c * cell + 0.06, r * cell + 0.06, 2 * cell - 0.12, 2 * cell - 0.12);
    ctx.fillStyle = '#7a3b69';
    for (const i of this.access) {
      const r = Math.floor(i / this.cols), c = i % this.cols;
      ctx.beginPath(); ctx.arc((c + 0.5) * cell, (r + 0.5) * cell, 0.25 * cell, 0, 2 * Math.PI); ctx.fill();
    }
    ctx.strokeStyle = '#e00'; ctx.lineWidth = 3 / cam.scale;
    for (const e of this.errors) for (const [r, c] of e.cells) ctx.strokeRect(c * cell + 0.08, r * cell + 0.08, cell - 0.16, cell - 0.16);
    document.getElementById('hud').textContent = `editor · ${this.rows} x ${this.cols} cells · tool: ${this.tool}`;
  }
}
