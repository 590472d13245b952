// Colour maps of the four fields and the colour bar beside the heart. Stops are sRGB
// triples at equal steps over [0, 1]; the ranges follow the renderer's (docs/rendering.md):
// activation 0..1, region by index, displacement from 0 and fiber strain symmetric about 0
// to the largest magnitude seen since the field was chosen.

const MAPS = {
  activation: [[0.05, 0.03, 0.2], [0.45, 0.05, 0.5], [0.85, 0.25, 0.25], [0.98, 0.65, 0.1], [0.98, 0.98, 0.6]],
  displacement: [[0.27, 0.0, 0.33], [0.23, 0.32, 0.55], [0.13, 0.57, 0.55], [0.37, 0.79, 0.38], [0.99, 0.91, 0.14]],
  fiber_strain: [[0.13, 0.4, 0.67], [0.57, 0.77, 0.87], [0.97, 0.97, 0.97], [0.96, 0.65, 0.51], [0.7, 0.09, 0.17]],
  region: [[0.86, 0.37, 0.34], [0.36, 0.6, 0.85], [0.55, 0.78, 0.4], [0.95, 0.75, 0.3], [0.7, 0.5, 0.85], [0.5, 0.8, 0.8]],
};
const UNITS = { activation: "1", displacement: "m", fiber_strain: "1", region: "" };

export class Colouring {
  constructor() { this.reset("activation", []); }

  reset(field, regionNames) {
    this.field = field;
    this.regionNames = regionNames;
    this.extent = field === "displacement" ? 1e-6 : 1e-3;
  }

  // [min, max] of the colour scale for this frame's values.
  range(values) {
    if (this.field === "activation") return [0, 1];
    if (this.field === "region") return [0, Math.max(1, this.regionNames.length - 1)];
    let m = 0;
    for (const v of values) m = Math.max(m, Math.abs(v));
    this.extent = Math.max(this.extent, m);
    return this.field === "displacement" ? [0, this.extent] : [-this.extent, this.extent];
  }

  // Fills rgb (3 per vertex) from the field values.
  paint(values, rgb) {
    const [lo, hi] = this.range(values);
    const stops = MAPS[this.field];
    for (let i = 0; i < values.length; i++) {
      let c;
      if (this.field === "region") c = stops[Math.round(values[i]) % stops.length];
      else c = sample(stops, (values[i] - lo) / (hi - lo));
      rgb[3 * i] = c[0]; rgb[3 * i + 1] = c[1]; rgb[3 * i + 2] = c[2];
    }
    return [lo, hi];
  }

  drawBar(canvas, labels, lo, hi) {
    const g = canvas.getContext("2d");
    const stops = MAPS[this.field];
    for (let y = 0; y < canvas.height; y++) {
      const t = 1 - y / (canvas.height - 1);
      const c = this.field === "region" ? stops[Math.min(Math.floor(t * this.regionNames.length), this.regionNames.length - 1) % stops.length] || stops[0] : sample(stops, t);
      g.fillStyle = `rgb(${c.map((v) => Math.round(255 * v)).join(",")})`;
      g.fillRect(0, y, canvas.width, 1);
    }
    const fmt = (v) => (Math.abs(v) >= 1e-2 || v === 0 ? v.toFixed(2) : v.toExponential(1));
    if (this.field === "region") {
      labels.max.textContent = this.regionNames[this.regionNames.length - 1] || "";
      labels.mid.textContent = "";
      labels.min.textContent = this.regionNames[0] || "";
    } else {
      labels.max.textContent = fmt(hi);
      labels.mid.textContent = fmt((lo + hi) / 2);
      labels.min.textContent = fmt(lo);
    }
    labels.title.textContent = this.field.replace("_", " ") + (UNITS[this.field] ? `, ${UNITS[this.field]}` : "");
  }
}

function sample(stops, t) {
  const x = Math.min(Math.max(Number.isFinite(t) ? t : 0, 0), 1) * (stops.length - 1);
  const i = Math.min(Math.floor(x), stops.length - 2);
  const f = x - i;
  return [0, 1, 2].map((k) => stops[i][k] + f * (stops[i + 1][k] - stops[i][k]));
}
