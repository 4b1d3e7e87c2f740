// The sketch pad: strokes drawn with mouse, pen or touch, a background photo behind them, or a
// picture of a drawing used as the sketch itself; the extracted contour is drawn on top.
//
// Coordinates are the sketch's own pixels (origin top-left, y down), as the API wants them: the
// canvas backing store is the sketch size (512 x 512 for strokes, the picture's size for a
// picture sketch) and CSS scales it to fit the page.

import { toBase64 } from './rpc.js';

const STROKE_SIZE = 512;

export class SketchPad extends EventTarget {
  /** @param {HTMLCanvasElement} canvas */
  constructor(canvas) {
    super();
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.strokes = []; // [{points: [[x, y], ...], pressure: [p, ...]}]
    this.current = null;
    this.pointerId = null;
    this.background = null; // {image: HTMLImageElement|ImageBitmap, bytes: Uint8Array}
    this.backgroundOpacity = 0.5;
    this.picture = null; // picture sketch: {image, bytes}
    this.contour = null; // [[x, y], ...] in sketch pixels, or null
    this.setSize(STROKE_SIZE, STROKE_SIZE);

    canvas.addEventListener('pointerdown', (e) => this.onDown(e));
    canvas.addEventListener('pointermove', (e) => this.onMove(e));
    canvas.addEventListener('pointerup', (e) => this.onUp(e));
    canvas.addEventListener('pointercancel', (e) => this.onUp(e));
  }

  setSize(w, h) {
    this.canvas.width = w;
    this.canvas.height = h;
    this.canvas.style.aspectRatio = `${w} / ${h}`;
    this.draw();
  }

  /** Sketch pixel coordinates of a pointer event. */
  toSketch(e) {
    const r = this.canvas.getBoundingClientRect();
    return [
      ((e.clientX - r.left) / r.width) * this.canvas.width,
      ((e.clientY - r.top) / r.height) * this.canvas.height,
    ];
  }

  onDown(e) {
    if (this.picture || this.pointerId !== null) return;
    if (e.pointerType === 'mouse' && e.button !== 0) return;
    e.preventDefault();
    this.canvas.setPointerCapture(e.pointerId);
    this.pointerId = e.pointerId;
    this.current = { points: [this.toSketch(e)], pressure: [this.pressureOf(e)] };
    this.strokes.push(this.current);
    this.draw();
  }

  onMove(e) {
    if (e.pointerId !== this.pointerId || !this.current) return;
    e.preventDefault();
    // Coalesced events keep a fast pen's full resolution.
    const events = e.getCoalescedEvents ? e.getCoalescedEvents() : [];
    for (const ev of events.length ? events : [e]) {
      const p = this.toSketch(ev);
      const last = this.current.points[this.current.points.length - 1];
      if (Math.hypot(p[0] - last[0], p[1] - last[1]) < 0.5) continue;
      this.current.points.push(p);
      this.current.pressure.push(this.pressureOf(ev));
      this.drawSegment(this.current, this.current.points.length - 1);
    }
  }

  onUp(e) {
    if (e.pointerId !== this.pointerId) return;
    this.pointerId = null;
    const s = this.current;
    this.current = null;
    if (s && s.points.length < 2) this.strokes.pop(); // a tap is not a stroke
    this.contour = null;
    this.draw();
    this.changed();
  }

  pressureOf(e) {
    // Mice report 0.5 while pressed; pens report real pressure; some touch screens report 0.
    return e.pointerType === 'pen' && e.pressure > 0 ? e.pressure : 0.5;
  }

  changed() {
    this.dispatchEvent(new Event('change'));
  }

  undo() {
    if (this.picture) {
      this.clearPicture();
      return;
    }
    if (!this.strokes.length) return;
    this.strokes.pop();
    this.contour = null;
    this.draw();
    this.changed();
  }

  clear() {
    this.strokes = [];
    this.contour = null;
    if (this.picture) this.clearPicture();
    else {
      this.draw();
      this.changed();
    }
  }

  clearPicture() {
    this.picture = null;
    this.contour = null;
    this.setSize(STROKE_SIZE, STROKE_SIZE);
    this.changed();
  }

  /** Use a picture of a drawing (PNG/JPEG File or Blob) as the sketch itself. */
  async setPicture(file) {
    const bytes = new Uint8Array(await file.arrayBuffer());
    const image = await createImageBitmap(file);
    this.strokes = [];
    this.picture = { image, bytes, name: file.name || 'picture' };
    this.contour = null;
    this.setSize(image.width, image.height);
    this.changed();
  }

  /** A background photo shown behind the strokes (stored with the object, not traced). */
  async setBackground(file) {
    const bytes = new Uint8Array(await file.arrayBuffer());
    const image = await createImageBitmap(file);
    this.background = { image, bytes, name: file.name || 'photo' };
    this.draw();
  }

  clearBackground() {
    this.background = null;
    this.draw();
  }

  setBackgroundOpacity(v) {
    this.backgroundOpacity = v;
    this.draw();
  }

  setContour(points) {
    this.contour = points && points.length ? points : null;
    this.draw();
  }

  isEmpty() {
    return !this.picture && this.strokes.length === 0;
  }

  /** The Sketch message (protobuf JSON) of what is on the pad. */
  sketch({ withBackground = true } = {}) {
    const out = {};
    if (this.picture) {
      out.image = toBase64(this.picture.bytes);
    } else {
      const round = (v) => Math.round(v * 100) / 100;
      out.strokesJson = JSON.stringify({
        width: this.canvas.width,
        height: this.canvas.height,
        strokes: this.strokes.map((s) => s.points.map(([x, y]) => [round(x), round(y)])),
      });
    }
    if (withBackground && this.background) out.backgroundImage = toBase64(this.background.bytes);
    return out;
  }

  /** Replace the strokes (e.g. a sample sketch loaded from JSON {width, height, strokes}). */
  loadStrokes(json) {
    this.picture = null;
    this.setSize(json.width || STROKE_SIZE, json.height || STROKE_SIZE);
    this.strokes = json.strokes.map((pts) => ({ points: pts.map((p) => [p[0], p[1]]), pressure: pts.map(() => 0.5) }));
    this.contour = null;
    this.draw();
    this.changed();
  }

  unit() {
    return Math.max(this.canvas.width, this.canvas.height) / STROKE_SIZE;
  }

  /** One segment of a stroke (from point i - 1 to i), pressure setting its width. */
  drawSegment(s, i) {
    const { ctx } = this;
    ctx.lineCap = 'round';
    ctx.strokeStyle = '#1d2433';
    ctx.lineWidth = this.unit() * (1.5 + 4 * s.pressure[i]);
    ctx.beginPath();
    ctx.moveTo(s.points[i - 1][0], s.points[i - 1][1]);
    ctx.lineTo(s.points[i][0], s.points[i][1]);
    ctx.stroke();
  }

  draw() {
    const { ctx, canvas } = this;
    const w = canvas.width;
    const h = canvas.height;
    ctx.save();
    ctx.fillStyle = '#fdfdfb';
    ctx.fillRect(0, 0, w, h);
    if (this.background) {
      // Fitted (contain) and centred; only shown, never traced.
      const img = this.background.image;
      const s = Math.min(w / img.width, h / img.height);
      ctx.globalAlpha = this.backgroundOpacity;
      ctx.drawImage(img, (w - img.width * s) / 2, (h - img.height * s) / 2, img.width * s, img.height * s);
      ctx.globalAlpha = 1;
    }
    if (this.picture) ctx.drawImage(this.picture.image, 0, 0);
    const unit = this.unit();
    for (const s of this.strokes) for (let i = 1; i < s.points.length; i++) this.drawSegment(s, i);
    if (this.contour) {
      ctx.beginPath();
      this.contour.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
      ctx.closePath();
      ctx.fillStyle = 'rgba(38, 132, 255, 0.10)';
      ctx.fill();
      ctx.lineWidth = 1.5 * unit;
      ctx.strokeStyle = '#e8590c';
      ctx.setLineDash([6 * unit, 4 * unit]);
      ctx.stroke();
      ctx.setLineDash([]);
      ctx.fillStyle = '#e8590c';
      for (const [x, y] of this.contour) {
        ctx.beginPath();
        ctx.arc(x, y, 2.5 * unit, 0, Math.PI * 2);
        ctx.fill();
      }
    }
    if (this.isEmpty() && !this.background) {
      ctx.fillStyle = '#9aa3b2';
      ctx.font = `${16 * unit}px system-ui, sans-serif`;
      ctx.textAlign = 'center';
      ctx.fillText('Draw a closed outline here', w / 2, h / 2);
    }
    ctx.restore();
  }
}
