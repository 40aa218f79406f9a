// Shared drawing: camera (pan / zoom), layout background, AGV bodies. No dependencies.

// Okabe-Ito, as in the MP4 renderer (render/frame.py).
export const CELL_COLORS = ['#fafafa', '#404040', '#a8d3f1', '#73c7ae', '#f6f0a3'];
export const STATUS_COLORS = ['#999999', '#0072B2', '#E69F00', '#D55E00']; // idle moving loaded failed
export const CORRIDOR = '#CC79A7';
export const FAILED = 7;

export function statusOf(state, loaded) {
  if (state === FAILED) return 3;
  if (loaded) return 2;
  return state === 0 ? 0 : 1;
}

export class Camera {
  // Screen px = o + world m * scale (CSS pixels). panButtons: mouse buttons that pan.
  constructor(canvas, onChange) {
    this.canvas = canvas; this.scale = 20; this.ox = 0; this.oy = 0; this.panButtons = [0, 1, 2];
    this.onChange = onChange || (() => {});
    this.dragging = null;
    canvas.addEventListener('wheel', (e) => {
      e.preventDefault();
      const r = canvas.getBoundingClientRect();
      const px = e.clientX - r.left, py = e.clientY - r.top;
      const f = Math.exp(-e.deltaY * 0.0015);
      const s = Math.min(400, Math.max(0.5, this.scale * f));
      this.ox = px - (px - this.ox) * (s / this.scale);
      this.oy = py - (py - this.oy) * (s / this.scale);
      this.scale = s; this.userMoved = true; this.onChange();
    }, { passive: false });
    canvas.addEventListener('contextmenu', (e) => e.preventDefault());
    canvas.addEventListener('mousedown', (e) => {
      if (!this.enabled || !this.panButtons.includes(e.button)) return;
      this.dragging = { x: e.clientX, y: e.clientY, ox: this.ox, oy: this.oy, moved: false };
    });
    window.addEventListener('mousemove', (e) => {
      const d = this.dragging; if (!d) return;
      const dx = e.clientX - d.x, dy = e.clientY - d.y;
      if (Math.abs(dx) + Math.abs(dy) > 3) d.moved = true;
      this.ox = d.ox + dx; this.oy = d.oy + dy; this.userMoved = d.moved || this.userMoved;
      this.onChange();
    });
    window.addEventListener('mouseup', () => { this.lastDragMoved = this.dragging && this.dragging.moved; this.dragging = null; });
    this.enabled = true;
  }
  fit(wm, hm) {
    const w = this.canvas.clientWidth, h = this.canvas.clientHeight;
    this.scale = Math.max(0.5, Math.min(w / wm, h / hm) * 0.96);
    this.ox = (w - wm * this.scale) / 2; this.oy = (h - hm * this.scale) / 2;
    this.onChange();
  }
  toWorld(px, py) { return [(px - this.ox) / this.scale, (py - this.oy) / this.scale]; }
  toScreen(x, y) { return [this.ox + x * this.scale, this.oy + y * this.scale]; }
  apply(ctx) {
    const d = window.devicePixelRatio || 1;
    ctx.setTransform(d * this.scale, 0, 0, d * this.scale, d * this.ox, d * this.oy);
  }
}

export function fitCanvas(canvas) {
  const d = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(canvas.clientWidth * d)), h = Math.max(1, Math.round(canvas.clientHeight * d));
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; return true; }
  return false;
}

// The floor as an image of one pixel per cell (drawn scaled with smoothing off).
export function layoutImage(rows, cols, grid) {
  const c = document.createElement('canvas');
  c.width = cols; c.height = rows;
  const ctx = c.getContext('2d');
  const img = ctx.createImageData(cols, rows);
  const rgb = CELL_COLORS.map((h) => [1, 3, 5].map((i) => parseInt(h.slice(i, i + 2), 16)));
  for (let i = 0; i < rows * cols; i++) {
    const v = rgb[grid.charCodeAt(i) - 48] || rgb[0];
    img.data[4 * i] = v[0]; img.data[4 * i + 1] = v[1]; img.data[4 * i + 2] = v[2]; img.data[4 * i + 3] = 255;
  }
  ctx.putImageData(img, 0, 0);
  return c;
}

export function drawFloor(ctx, cam, img, rows, cols, cell, extras) {
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(img, 0, 0, cols * cell, rows * cell);
  if (cam.scale * cell >= 8) {           // grid lines when cells are big enough
    ctx.beginPath();
    for (let r = 0; r <= rows; r++) { ctx.moveTo(0, r * cell); ctx.lineTo(cols * cell, r * cell); }
    for (let c = 0; c <= cols; c++) { ctx.moveTo(c * cell, 0); ctx.lineTo(c * cell, rows * cell); }
    ctx.strokeStyle = '#dedede'; ctx.lineWidth = 1 / cam.scale; ctx.stroke();
  }
  if (extras) {
    ctx.lineWidth = 1.5 / cam.scale;
    ctx.strokeStyle = '#3a7fb0';
    for (const [r, c, s] of extras.shelves || []) if (s > 1) ctx.strokeRect(c * cell + 0.05, r * cell + 0.05, s * cell - 0.1, s * cell - 0.1);
    ctx.fillStyle = '#7a3b69';
    for (const [r, c] of extras.access || []) {
      ctx.beginPath(); ctx.arc((c + 0.5) * cell, (r + 0.5) * cell, 0.22 * cell, 0, 2 * Math.PI); ctx.fill();
    }
  }
}

export function drawCorridors(ctx, cam, corridors) {
  for (const cor of corridors || []) {
    ctx.beginPath();
    for (const ring of cor.zone || []) {
      ring.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
      ctx.closePath();
    }
    ctx.fillStyle = 'rgba(204,121,167,0.4)'; ctx.fill('evenodd');
    ctx.strokeStyle = CORRIDOR; ctx.lineWidth = 2 / cam.scale; ctx.stroke();
  }
}

// Bodies: rotated rectangles, batched by status colour. pos: {x, y, h} Float32Arrays.
export function drawBodies(ctx, cam, n, x, y, h, status, body, opts = {}) {
  const minM = (opts.minPx || 3) / cam.scale;
  const paths = STATUS_COLORS.map(() => new Path2D());
  for (let i = 0; i < n; i++) {
    const L = Math.max(body[2 * i], minM) / 2, W = Math.max(body[2 * i + 1], minM) / 2;
    const c = Math.cos(h[i]), s = Math.sin(h[i]);
    const p = paths[status[i]] || paths[1];
    const cx = x[i], cy = y[i];
    p.moveTo(cx + c * L - s * W, cy + s * L + c * W);
    p.lineTo(cx + c * L + s * W, cy + s * L - c * W);
    p.lineTo(cx - c * L + s * W, cy - s * L - c * W);
    p.lineTo(cx - c * L - s * W, cy - s * L + c * W);
    p.closePath();
  }
  ctx.globalAlpha = opts.alpha || 1;
  paths.forEach((p, k) => {
    if (opts.ghost) { ctx.strokeStyle = STATUS_COLORS[k]; ctx.lineWidth = 1.5 / cam.scale; ctx.stroke(p); }
    else { ctx.fillStyle = STATUS_COLORS[k]; ctx.fill(p); }
  });
  ctx.globalAlpha = 1;
  if (opts.ghost) return;
  const px = Math.min(body[0] || 0.7, body[1] || 0.7) * cam.scale;
  if (px >= 7) {                   // heading marks, failure crosses
    const marks = new Path2D(), crosses = new Path2D();
    for (let i = 0; i < n; i++) {
      const L = body[2 * i] / 2, c = Math.cos(h[i]), s = Math.sin(h[i]);
      marks.moveTo(x[i], y[i]); marks.lineTo(x[i] + c * L, y[i] + s * L);
      if (status[i] === 3) {
        const q = 0.3 * body[2 * i];
        crosses.moveTo(x[i] - q, y[i] - q); crosses.lineTo(x[i] + q, y[i] + q);
        crosses.moveTo(x[i] + q, y[i] - q); crosses.lineTo(x[i] - q, y[i] + q);
      }
    }
    ctx.lineWidth = 1.5 / cam.scale; ctx.strokeStyle = '#fff'; ctx.stroke(marks); ctx.stroke(crosses);
  }
  if (px >= 16 && opts.labels !== false) {
    ctx.save(); ctx.setTransform(1, 0, 0, 1, 0, 0);
    const d = window.devicePixelRatio || 1;
    ctx.font = `${11 * d}px system-ui`; ctx.fillStyle = '#111'; ctx.textAlign = 'center';
    for (let i = 0; i < n; i++) {
      const [sx, sy] = cam.toScreen(x[i], y[i]);
      ctx.fillText(String(i), sx * d, (sy - body[2 * i] * cam.scale * 0.55) * d);
    }
    ctx.restore();
  }
}

export function downloadCanvas(canvas, name) {
  canvas.toBlob((blob) => {
    const a = document.createElement('a');
    a.href = URL.createObjectURL(blob); a.download = name;
    document.body.appendChild(a); a.click(); a.remove();
    setTimeout(() => URL.revokeObjectURL(a.href), 5000);
  }, 'image/png');
}
