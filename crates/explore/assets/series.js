/*
 * The curves' arithmetic (no DOM: node's test runner imports it): a channel's colour within its
 * group, one curve resampled onto another's times, runs of flags (the sweep's shaded values
 * outside the training range), and whether the solver's answer lies inside the prediction's
 * bands and intervals.
 */

// Series colours (the first ten of a group; channelColor makes more).
const PALETTE = ['#1f77b4', '#d62728', '#2ca02c', '#9467bd', '#ff7f0e',
  '#17becf', '#8c564b', '#e377c2', '#7f7f7f', '#bcbd22'];

/** `h` (degrees), `s`, `l` (0..1) as `#rrggbb`. */
function hslHex(h, sat, light) {
  const f = (n) => {
    const k = (n + h / 30) % 12;
    const c = light - sat * Math.min(light, 1 - light) * Math.max(-1, Math.min(k - 3, 9 - k, 1));
    return Math.round(c * 255).toString(16).padStart(2, '0');
  };
  return `#${f(0)}${f(8)}${f(4)}`;
}

/**
 * The colour of the `i`-th channel of a group: the palette first, then hues a golden angle
 * apart at two lightnesses, so no two channels of a group share one.
 */
export function channelColor(i) {
  if (i < PALETTE.length) return PALETTE[i];
  const j = i - PALETTE.length;
  return hslHex((15 + j * 137.508) % 360, 0.6, j % 2 === 0 ? 0.36 : 0.52);
}

/** y series of `y` at x positions `x` onto `xRef`, linearly interpolated (null outside). */
export function alignTo(xRef, x, y) {
  if (!y) return xRef.map(() => null);
  if (x.length === xRef.length && x[0] === xRef[0] && x[x.length - 1] === xRef[xRef.length - 1]) return y;
  const out = new Array(xRef.length).fill(null);
  let j = 0;
  for (let i = 0; i < xRef.length; i++) {
    const xi = xRef[i];
    while (j < x.length - 2 && x[j + 1] < xi) j++;
    if (xi < x[0] || xi > x[x.length - 1]) continue;
    const x0 = x[j];
    const x1 = x[j + 1];
    const y0 = y[j];
    const y1 = y[j + 1];
    if (x1 === undefined || y0 == null || y1 == null) { out[i] = y0 ?? null; continue; }
    out[i] = x1 === x0 ? y0 : y0 + ((y1 - y0) * (xi - x0)) / (x1 - x0);
  }
  return out;
}

/** Runs of consecutive `true` in `flags`, as [first, last] index pairs. */
export function runsOf(flags) {
  const runs = [];
  let start = -1;
  flags.forEach((f, i) => {
    if (f && start < 0) start = i;
    if (!f && start >= 0) { runs.push([start, i - 1]); start = -1; }
  });
  if (start >= 0) runs.push([start, flags.length - 1]);
  return runs;
}

/** Whether the solve's index value lies inside the prediction's interval (null: unknown). */
export function indexInside(pred, solve, name) {
  const p = (pred.indices || []).find((x) => x.name === name);
  const s = (solve.indices || []).find((x) => x.name === name);
  if (!p || !s || p.lo == null || p.hi == null) return null;
  if (solve.coverage === pred.coverage && solve.index_inside && name in solve.index_inside) {
    return solve.index_inside[name];
  }
  return p.lo <= s.value && s.value <= p.hi;
}

/**
 * The fraction of the solver curve's rows inside the prediction's band (null: no band): the
 * solve's own answer at the prediction's level (every banded channel, plotted or not), else
 * counted against the band the prediction carries.
 */
export function channelInside(pred, solve, name) {
  const given = solve.inside && solve.inside[name];
  if (given && pred && solve.coverage === pred.coverage) return given.fraction_inside;
  const b = pred && pred.bands && pred.bands[name];
  if (!b) return null;
  const x = alignTo(pred.t, solve.t, solve.channels && solve.channels[name]);
  let n = 0;
  let inside = 0;
  x.forEach((v, i) => {
    if (v == null) return;
    n += 1;
    if (b.lo[i] <= v && v <= b.hi[i]) inside += 1;
  });
  return n ? inside / n : null;
}
