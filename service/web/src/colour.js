// False colour for illuminance: the "turbo" colour map (the one service/maps.py draws its PNG maps with),
// a linear or logarithmic scale shared by every sensor of the scene, and the legend that shows it.

/** Turbo colour map, polynomial approximation (A. Mikhailov, Google, 2019): t in [0, 1] -> [r, g, b] in [0, 1]. */
export function turbo(t) {
  t = Math.min(1, Math.max(0, t));
  const r = 0.13572138 + t * (4.61539260 + t * (-42.66032258 + t * (132.13108234 + t * (-152.94239396 + t * 59.28637943))));
  const g = 0.09140261 + t * (2.19418839 + t * (4.84296658 + t * (-14.18503333 + t * (4.27729857 + t * 2.82956604))));
  const b = 0.10667330 + t * (12.64194608 + t * (-60.58204836 + t * (110.36276771 + t * (-89.90310912 + t * 27.34824973))));
  return [r, g, b].map((c) => Math.min(1, Math.max(0, c)));
}

/** Decades a log scale spans below its top (lux below vmax / 10^DECADES show as the bottom colour). */
export const DECADES = 3;

/**
 * The colour scale: `mode` "linear" (0 .. vmax) or "log" (vmax / 10^DECADES .. vmax), in lux.
 * `vmax` is the top of the scene's well-measured sensor results (`vmaxOf` in main.js; 1 lx when there is none
 * yet): brighter values saturate at the top colour, and the legend's top label says "≥".
 */
export class Scale {
  constructor(mode = "linear", vmax = 1) {
    this.mode = mode;
    this.vmax = vmax > 0 ? vmax : 1;
  }

  get vmin() {
    return this.mode === "log" ? this.vmax / 10 ** DECADES : 0;
  }

  /** Position of `lux` on the scale, 0 .. 1. */
  norm(lux) {
    if (!(lux > 0)) return 0;
    if (this.mode === "log") return Math.log10(lux / this.vmin) / DECADES;
    return lux / this.vmax;
  }

  /** The lux at position `t` (0 .. 1) of the scale: the legend's labels. */
  at(t) {
    return this.mode === "log" ? this.vmin * 10 ** (t * DECADES) : t * this.vmax;
  }
}

/** "1234.5 lx" with about three significant digits. */
export function formatLux(lux) {
  if (!Number.isFinite(lux)) return "—";
  const digits = Math.abs(lux) >= 100 ? 0 : Math.abs(lux) >= 10 ? 1 : 2;
  return `${lux.toFixed(digits)} lx`;
}

/** Paint the legend's gradient into `canvas` and its labels (bottom, middle, top of the scale) into `labels`. */
export function drawLegend(canvas, labels, scale) {
  const ctx = canvas.getContext("2d");
  for (let x = 0; x < canvas.width; x++) {
    const [r, g, b] = turbo(x / (canvas.width - 1));
    ctx.fillStyle = `rgb(${Math.round(255 * r)},${Math.round(255 * g)},${Math.round(255 * b)})`;
    ctx.fillRect(x, 0, 1, canvas.height);
  }
  labels.replaceChildren(...[0, 0.5, 1].map((t) => {
    const span = document.createElement("span");
    span.textContent = (t === 1 ? "≥ " : "") + formatLux(scale.at(t));
    return span;
  }));
}

/** RGBA bytes (nu × nv texels, row j = cell row j) of a grid result `lux` (nv rows of nu values) on `scale`. */
export function gridTexels(lux, scale) {
  const nv = lux.length;
  const nu = nv ? lux[0].length : 0;
  const data = new Uint8Array(nu * nv * 4);
  for (let j = 0; j < nv; j++) {
    for (let i = 0; i < nu; i++) {
      const [r, g, b] = turbo(scale.norm(lux[j][i]));
      const k = 4 * (j * nu + i);
      data[k] = Math.round(255 * r);
      data[k + 1] = Math.round(255 * g);
      data[k + 2] = Math.round(255 * b);
      data[k + 3] = 255;
    }
  }
  return data;
}
