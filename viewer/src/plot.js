// The error-per-frame plot: the largest joint error of each frame (and the mean over joints),
// the tolerance the asset was encoded for, a cursor at the current time; a click or a drag seeks.

export class ErrorPlot {
  constructor(canvas, onSeek) {
    this.canvas = canvas;
    this.data = null;
    this.frame = 0;
    let dragging = false;
    const seek = (e) => {
      if (!this.data) return;
      const r = canvas.getBoundingClientRect();
      const x = (e.clientX - r.left - this._left) / Math.max(1, r.width - this._left - this._right);
      onSeek(Math.min(Math.max(x, 0), 1) * (this.data.perFrame.length - 1));
    };
    canvas.addEventListener("pointerdown", (e) => { dragging = true; canvas.setPointerCapture(e.pointerId); seek(e); });
    canvas.addEventListener("pointermove", (e) => { if (dragging) seek(e); });
    canvas.addEventListener("pointerup", () => { dragging = false; });
    this._left = 60;
    this._right = 8;
    new ResizeObserver(() => this.draw()).observe(canvas);
  }

  set(data, toleranceCm) {
    this.data = data;
    this.tolerance = toleranceCm;
    this.draw();
  }

  cursor(frame) {
    this.frame = frame;
    this.draw();
  }

  draw() {
    const c = this.canvas, dpr = window.devicePixelRatio || 1;
    const w = c.clientWidth, h = c.clientHeight;
    if (!w || !h) return;
    c.width = Math.round(w * dpr);
    c.height = Math.round(h * dpr);
    const g = c.getContext("2d");
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    g.clearRect(0, 0, w, h);
    g.font = "11px system-ui, sans-serif";
    g.fillStyle = "#9aa0aa";
    if (!this.data) {
      g.fillText("no original given (mocodec view --original FILE): no error per frame", this._left, h / 2);
      return;
    }
    const { perFrame, perFrameMean } = this.data;
    const top = 8, bottom = 18, left = this._left, right = this._right;
    const frames = perFrame.length;
    const ymax = niceCeil(Math.max(this.tolerance || 0, ...perFrame) * 1.05 || 1);
    const X = (f) => left + (f / Math.max(1, frames - 1)) * (w - left - right);
    const Y = (v) => top + (1 - v / ymax) * (h - top - bottom);
    g.strokeStyle = "#3a3f4a";
    g.beginPath();
    for (const v of [0, ymax / 2, ymax]) { g.moveTo(left, Y(v)); g.lineTo(w - right, Y(v)); }
    g.stroke();
    g.textAlign = "right";
    for (const v of [0, ymax / 2, ymax]) g.fillText(`${+v.toPrecision(3)} cm`, left - 4, Y(v) + 4);
    g.textAlign = "left";
    g.fillText(`frame 0`, left, h - 4);
    g.textAlign = "right";
    g.fillText(`${frames - 1}`, w - right, h - 4);
    const line = (values, colour) => {
      g.strokeStyle = colour;
      g.beginPath();
      values.forEach((v, f) => (f ? g.lineTo(X(f), Y(v)) : g.moveTo(X(f), Y(v))));
      g.stroke();
    };
    line(perFrameMean, "#5f7fa8");
    line(perFrame, "#ffb347");
    if (this.tolerance) {
      g.setLineDash([5, 4]);
      g.strokeStyle = "#e05d5d";
      g.beginPath(); g.moveTo(left, Y(this.tolerance)); g.lineTo(w - right, Y(this.tolerance)); g.stroke();
      g.setLineDash([]);
      g.fillStyle = "#e05d5d";
      g.textAlign = "right";
      g.fillText(`tolerance ${this.tolerance} cm`, w - right, Y(this.tolerance) - 3);
    }
    g.strokeStyle = "#ffffff";
    g.beginPath(); g.moveTo(X(this.frame), top); g.lineTo(X(this.frame), h - bottom); g.stroke();
  }
}

function niceCeil(v) {
  const p = 10 ** Math.floor(Math.log10(v));
  for (const m of [1, 2, 2.5, 5, 10]) if (m * p >= v) return m * p;
  return 10 * p;
}
