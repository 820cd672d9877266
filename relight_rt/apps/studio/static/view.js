// Zoom and pan of the photo area. One transform on the view element, which holds the live preview (canvas),
// the full result and the original photo, each laid out at the photo's full resolution: whatever is shown
// zooms and pans alike. Zoom 100 % = one photo pixel per device pixel.

const MAX_PERCENT = 1600;

// Where the face is, roughly, in full-resolution pixels (x right, y down), from the person's mask at any
// resolution: the top of the mask, half a head lower (a head's height taken as 1.3 × the widest row in the
// mask's top 8 %: right for an upright person seen whole; for a head-and-shoulders photo it lands higher up
// on the head). The centre of the photo when the mask is empty.
export function facePoint(mask, width, height, fullWidth, fullHeight) {
  const rows = new Float64Array(height);
  let widest = 0;
  for (let y = 0; y < height; y++) {
    let s = 0;
    for (let x = 0, o = y * width; x < width; x++) s += mask[o + x];
    rows[y] = s;
    widest = Math.max(widest, s);
  }
  if (widest < 1) return [fullWidth / 2, fullHeight / 2];
  const seen = (y) => rows[y] > Math.max(0.5, 0.05 * widest);
  let top = 0, bottom = height - 1;
  while (top < bottom && !seen(top)) top++;
  while (bottom > top && !seen(bottom)) bottom--;
  const band = Math.max(1, Math.round(0.08 * (bottom - top + 1)));
  let head = 0;
  for (let y = top; y < top + band; y++) head = Math.max(head, rows[y]);
  const cy = top + Math.min(0.65 * head, 0.5 * (bottom - top + 1));
  // across: the mask's centre of mass over the head's rows
  let m = 0, mx = 0;
  for (let y = top; y <= Math.min(bottom, Math.round(2 * cy - top)); y++) {
    for (let x = 0, o = y * width; x < width; x++) { m += mask[o + x]; mx += mask[o + x] * (x + 0.5); }
  }
  const cx = m > 0 ? mx / m : width / 2;
  return [(cx * fullWidth) / width, ((cy + 0.5) * fullHeight) / height];
}

export class ZoomView {
  // frame: the clipping element that receives the wheel and the drags; view: its child to transform;
  // width, height: the photo's full size; onChange(view) after every change.
  constructor(frame, view, width, height, { onChange = () => {}, face = null } = {}) {
    this.frame = frame;
    this.view = view;
    this.width = width;
    this.height = height;
    this.face = face || [width / 2, height / 2];
    this.onChange = onChange;
    this.scale = 1;  // CSS pixels per photo pixel
    this.x = 0;      // where the photo's top-left corner is in the frame, CSS pixels
    this.y = 0;
    this.mode = "fit";
    view.style.width = `${width}px`;
    view.style.height = `${height}px`;
    frame.addEventListener("wheel", (e) => this.wheel(e), { passive: false });
    let drag = null;
    frame.addEventListener("pointerdown", (e) => {
      if (e.button !== 0) return;
      e.preventDefault();
      frame.setPointerCapture(e.pointerId);
      drag = { id: e.pointerId, x: e.clientX, y: e.clientY };
      frame.classList.add("dragging");
    });
    frame.addEventListener("pointermove", (e) => {
      if (!drag || e.pointerId !== drag.id) return;
      this.panBy(e.clientX - drag.x, e.clientY - drag.y);
      drag.x = e.clientX;
      drag.y = e.clientY;
    });
    const end = () => { drag = null; frame.classList.remove("dragging"); };
    frame.addEventListener("pointerup", end);
    frame.addEventListener("pointercancel", end);
    frame.addEventListener("dblclick", (e) => {  // fit <-> 100 % at the pointer
      if (this.mode === "fit") {
        const [fx, fy] = this.framePoint(e);
        this.zoomAt(1 / this.dpr, (fx - this.x) / this.scale, (fy - this.y) / this.scale, fx, fy);
      } else {
        this.fit();
      }
    });
    // a resized frame (the window, or the export box below growing): refit, or keep the middle where it was
    this.size = [frame.clientWidth, frame.clientHeight];
    new ResizeObserver(() => {
      const [w0, h0] = this.size;
      this.size = [frame.clientWidth, frame.clientHeight];
      if (this.mode === "fit") return this.fit();
      this.x += (this.size[0] - w0) / 2;
      this.y += (this.size[1] - h0) / 2;
      this.place();
    }).observe(frame);
    this.fit();
  }

  get dpr() { return window.devicePixelRatio || 1; }

  // the zoom in percent: device pixels per photo pixel × 100
  get percent() { return this.scale * this.dpr * 100; }

  fitScale() {
    const w = this.frame.clientWidth, h = this.frame.clientHeight;
    return w > 0 && h > 0 ? Math.min(w / this.width, h / this.height) : 1;
  }

  framePoint(event) {
    const r = this.frame.getBoundingClientRect();
    return [event.clientX - r.left, event.clientY - r.top];
  }

  // the whole photo, centred
  fit() {
    this.mode = "fit";
    this.scale = this.fitScale();
    this.place();
  }

  // 100 %, with the photo point (px, py) (default: the face) at the middle of the frame where the photo allows
  actualSize(px = this.face[0], py = this.face[1]) {
    this.zoomAt(1 / this.dpr, px, py, this.frame.clientWidth / 2, this.frame.clientHeight / 2);
  }

  // zoom to `scale` CSS pixels per photo pixel with photo point (px, py) at frame point (fx, fy)
  zoomAt(scale, px, py, fx, fy) {
    const lo = Math.min(this.fitScale(), 1 / this.dpr), hi = MAX_PERCENT / 100 / this.dpr;
    this.scale = Math.min(hi, Math.max(lo, scale));
    this.mode = "free";
    this.x = fx - px * this.scale;
    this.y = fy - py * this.scale;
    this.place();
  }

  wheel(e) {
    e.preventDefault();
    const step = e.deltaMode === 1 ? 40 : e.deltaMode === 2 ? 400 : 1;  // lines, pages -> pixels
    const [fx, fy] = this.framePoint(e);
    const px = (fx - this.x) / this.scale, py = (fy - this.y) / this.scale;
    this.zoomAt(this.scale * Math.exp(-e.deltaY * step * 0.002), px, py, fx, fy);
  }

  panBy(dx, dy) {
    this.mode = "free";
    this.x += dx;
    this.y += dy;
    this.place();
  }

  // keep the photo in the frame (centred on an axis where it is smaller), on whole device pixels
  place() {
    const fw = this.frame.clientWidth, fh = this.frame.clientHeight, dpr = this.dpr;
    const clamp = (t, size, room) => (size <= room ? (room - size) / 2 : Math.min(0, Math.max(room - size, t)));
    this.x = Math.round(clamp(this.x, this.width * this.scale, fw) * dpr) / dpr;
    this.y = Math.round(clamp(this.y, this.height * this.scale, fh) * dpr) / dpr;
    this.view.style.transform = `translate(${this.x}px, ${this.y}px) scale(${this.scale})`;
    this.view.classList.toggle("pixels", this.percent >= 199.5);  // 2x and more: each pixel as a sharp square
    this.onChange(this);
  }
}
