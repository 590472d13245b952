// The circulation panel (docs/web.md): a run's pressure-volume loops, LV red and RV blue, with
// the newest point marked, and its pressures, volumes and last beat in numbers. Fed by the
// bridge's "circulation" messages; hidden for a run without a circulation. The loops are
// redrawn at most 10 times a second, from the page's animation loop: the samples come at the
// state rate, and a canvas redrawn for each one kept a software-rendered page (headless
// Chromium, SwiftShader) too busy to answer.

const $ = (id) => document.getElementById(id);
const KEEP = 600; // points drawn per ventricle (the bridge's trail)
const LV = "#e53935";
const RV = "#1e88e5";
const REDRAW_MS = 100;

const fixed = (v, digits) => (v === null || v === undefined ? "–" : v.toFixed(digits));

export class CirculationPanel {
  constructor() {
    this.points = []; // [frame, time s, LV mL, LV mmHg, RV mL, RV mmHg]
    this.run = null;
    this.stale = false;  // points arrived since the last drawing
    this.drawnAt = -Infinity;
  }

  // From the animation loop: redraws when points came and REDRAW_MS have passed.
  drawIfDue(now) {
    if (!this.stale || now - this.drawnAt < REDRAW_MS) return;
    this.draw();
    this.drawnAt = now;
  }

  // A new run (or a run switched to): no points until its circulation arrives.
  clear(run) {
    this.points = [];
    this.run = run;
    $("circulation").hidden = true;
  }

  update(msg) {
    if (msg.run !== this.run || msg.restart) this.points = [];
    this.run = msg.run;
    this.points.push(...msg.points);
    if (this.points.length > KEEP) this.points.splice(0, this.points.length - KEEP);
    $("circulation").hidden = false;
    const n = msg.now;
    $("cv-lv").textContent = `${fixed(n.lv_pressure_mmhg, 1)} mmHg, ${fixed(n.lv_volume_ml, 2)} mL`;
    $("cv-rv").textContent = `${fixed(n.rv_pressure_mmhg, 1)} mmHg, ${fixed(n.rv_volume_ml, 2)} mL`;
    $("cv-aortic").textContent = `${fixed(n.aortic_pressure_mmhg, 1)} mmHg`;
    $("cv-pulmonary").textContent = `${fixed(n.pulmonary_arterial_pressure_mmhg, 1)} mmHg`;
    const b = msg.beat;
    $("cv-beat").textContent = b
      ? `${b.beat}: LV SV ${fixed(b.lv_stroke_volume_ml, 2)} mL, EF ${fixed(b.lv_ejection_fraction, 3)}, peak ${fixed(b.lv_peak_pressure_mmhg, 1)} mmHg; aortic ${fixed(b.aortic_max_mmhg, 0)}/${fixed(b.aortic_min_mmhg, 0)} mmHg`
      : "none complete yet";
    this.stale = true;
  }

  // Both loops on one pair of axes: volume (mL) across, pressure (mmHg) up, ranges from
  // the points shown.
  draw() {
    this.stale = false;
    const canvas = $("pv-loop");
    const g = canvas.getContext("2d", { willReadFrequently: true }); // a plain CPU canvas: small, cheap
    const w = canvas.width, h = canvas.height, m = { left: 34, right: 6, top: 6, bottom: 22 };
    g.fillStyle = "#1d2026";
    g.fillRect(0, 0, w, h);
    if (this.points.length === 0) return;
    let vlo = Infinity, vhi = -Infinity, plo = 0, phi = -Infinity;
    for (const p of this.points) {
      vlo = Math.min(vlo, p[2], p[4]); vhi = Math.max(vhi, p[2], p[4]);
      plo = Math.min(plo, p[3], p[5]); phi = Math.max(phi, p[3], p[5]);
    }
    if (!(vhi > vlo)) { vhi = vlo + 1; }
    if (!(phi > plo)) { phi = plo + 1; }
    const x = (v) => m.left + ((v - vlo) / (vhi - vlo)) * (w - m.left - m.right);
    const y = (p) => h - m.bottom - ((p - plo) / (phi - plo)) * (h - m.top - m.bottom);
    g.strokeStyle = "#889";
    g.lineWidth = 1;
    g.strokeRect(m.left, m.top, w - m.left - m.right, h - m.top - m.bottom);
    g.fillStyle = "#9ab";
    g.font = "10px system-ui, sans-serif";
    g.fillText(`${phi.toFixed(0)}`, 2, m.top + 8);
    g.fillText(`${plo.toFixed(0)}`, 2, h - m.bottom);
    g.fillText("mmHg", 2, h / 2);
    g.fillText(`${vlo.toFixed(1)}`, m.left, h - 6);
    g.fillText(`${vhi.toFixed(1)} mL`, w - m.right - 44, h - 6);
    for (const [vi, pi, colour] of [[2, 3, LV], [4, 5, RV]]) {
      g.strokeStyle = colour;
      g.lineWidth = 1.5;
      g.beginPath();
      this.points.forEach((p, i) => (i ? g.lineTo(x(p[vi]), y(p[pi])) : g.moveTo(x(p[vi]), y(p[pi]))));
      g.stroke();
      const last = this.points[this.points.length - 1];
      g.fillStyle = colour;
      g.beginPath();
      g.arc(x(last[vi]), y(last[pi]), 3.5, 0, 2 * Math.PI);
      g.fill();
    }
  }
}
