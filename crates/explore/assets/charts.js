/*
 * The response charts (uPlot, the vendored global `uPlot`): one section per channel group with
 * its channel picker, the surrogate's curves (solid) with their bands (shaded in the channel's
 * colour), the solver's (dashed) beside the prediction of the same design, design A's (grey),
 * synchronised cursors, each channel's error and inside-the-band mark after a solve; and the
 * drawing helpers the sweep's chart shares (ticks, legend values, bands, widths).
 * Test hooks: window.explorerCharts = {GROUP: uPlot, sweep: uPlot} (`u.explorerBands`: the
 * bands a chart shades; `u.explorerTicks`: its tick labels), window.explorerBandAlpha.
 */
import { $, el } from './dom.js';
import { fmt, fmtPercent, withAlpha, withUnit } from './format.js';
import { alignTo, channelColor, channelInside } from './series.js';
import { isLarge } from './verdicts.js';
import { solveOverlay } from './state.js';
import { insideMark } from './tables.js';

/** Chart sections, in page order; a channel's `group` picks its section. */
const GROUPS = [
  { key: 'displacement', title: 'Displacements', height: 230 },
  { key: 'velocity', title: 'Velocities', height: 230 },
  { key: 'acceleration', title: 'Accelerations', height: 230 },
  { key: 'force', title: 'Forces', height: 230 },
  { key: 'excitation', title: 'Excitation', height: 200 },
];
const DEFAULT_SELECTED_PER_GROUP = 2;
const SYNC_KEY = 'pino-explorer';
const PIN_COLOR = '#9aa0a6';
/** Opacity of the bands' fill (the channel's colour). */
export const BAND_ALPHA = 0.22;
export const SWEEP_HEIGHT = 320;
window.explorerBandAlpha = BAND_ALPHA;
window.explorerCharts = {};

/**
 * One section per group with channels; `onPick(group, channel, checked)` after a channel was
 * (un)ticked and its chart redrawn.
 */
export function buildChartSections(st, onPick) {
  const host = $('#charts');
  host.textContent = '';
  st.groups = [];
  for (const g of GROUPS) {
    // Copies of the summary's channels with a colour each, distinct within the group (the
    // summary stays as received).
    const channels = st.summary.channels.filter((c) => c.group === g.key)
      .map((c, i) => ({ ...c, color: channelColor(i) }));
    if (!channels.length) continue;
    const group = { ...g, channels, selected: new Set(), chart: null, structure: '' };
    channels.forEach((c, i) => {
      if (i < DEFAULT_SELECTED_PER_GROUP) group.selected.add(c.name);
    });
    const picker = el('div', { class: 'channel-picker' });
    for (const c of channels) {
      const box = el('input', { type: 'checkbox', value: c.name, checked: group.selected.has(c.name) });
      box.addEventListener('change', () => {
        if (box.checked) group.selected.add(c.name); else group.selected.delete(c.name);
        renderChart(st, group);
        onPick(group, c, box.checked);
      });
      const swatch = el('span', { class: 'swatch' });
      swatch.style.backgroundColor = c.color;
      picker.append(el('label', { class: 'channel', dataset: { channel: c.name } },
        box,
        swatch,
        el('span', { class: 'channel-name' }, c.name),
        el('span', { class: 'channel-unit' }, c.unit ? `[${c.unit}]` : ''),
        el('span', { class: 'channel-error' })));
    }
    group.chartEl = el('div', { class: 'chart' });
    group.lineKey = el('span', { class: 'line-key', 'aria-label': 'line styles' });
    group.section = el('section', { class: `card chart-section group-${g.key}`, dataset: { group: g.key } },
      el('div', { class: 'card-head' }, el('h2', {}, g.title), group.lineKey),
      picker,
      group.chartEl);
    host.append(group.section);
    st.groups.push(group);
  }
}

/** A tick number formatter for the axes (the values drawn kept in `u.explorerTicks`). */
export function tickValues(u, splits, axisIdx) {
  const out = splits.map((v) => (v == null ? '' : fmt(v, 3)));
  u.explorerTicks = u.explorerTicks || {};
  u.explorerTicks[axisIdx] = out;
  return out;
}

/** The key of a chart's line styles: the surrogate's, the solver's and A's when shown. */
function renderLineKey(group, solve, pinned) {
  const item = (kind, text) => el('span', { class: 'key-item', dataset: { kind } },
    el('span', { class: `key-line ${kind}` }), text);
  const items = [item('surrogate', 'surrogate')];
  if (solve) items.push(item('solver', 'solver'));
  if (pinned) items.push(item('pinned', 'A (pinned)'));
  group.lineKey.replaceChildren(...items);
}

export function legendValue(_u, v) {
  return v == null ? '—' : fmt(v, 4);
}

export function chartWidth(node) {
  return Math.max(240, Math.floor(node.clientWidth || node.parentElement.clientWidth || 600));
}

/** Redraws one section's chart: rebuilt when its series change, else just setData. */
export function renderChart(st, group) {
  const pred = st.prediction && st.prediction.answer;
  if (!pred) return;
  const solve = solveOverlay(st);
  const pinned = st.pinned;
  const selected = group.channels.filter((c) => group.selected.has(c.name));
  renderLineKey(group, solve, pinned);

  // Per channel: its prediction, the solver's (dashed) and A's (grey) when present.
  const plan = [];
  for (const c of selected) {
    plan.push({ kind: 'pred', c });
    if (solve) plan.push({ kind: 'solver', c });
    if (pinned) plan.push({ kind: 'A', c });
  }
  const units = [...new Set(selected.map((c) => c.unit || ''))];
  const scaleOf = (unit) => `y${units.indexOf(unit)}`;
  const structure = JSON.stringify(plan.map((s) => [s.kind, s.c.name]));

  const x = pred.t;
  const data = [x];
  for (const s of plan) {
    if (s.kind === 'pred') data.push(pred.channels[s.c.name] || x.map(() => null));
    else if (s.kind === 'solver') data.push(alignTo(x, solve.t, solve.channels && solve.channels[s.c.name]));
    else data.push(alignTo(x, pinned.prediction.t, pinned.prediction.channels[s.c.name]));
  }

  // The bands of the plotted predictions (drawn under the curves by the drawAxes hook).
  group.bands = [];
  const bands = pred.bands || {};
  for (const c of selected) {
    const b = bands[c.name];
    if (!b) continue;
    group.bands.push({
      channel: c.name, color: c.color, fill: withAlpha(c.color, BAND_ALPHA),
      scale: scaleOf(c.unit || ''), lo: b.lo, hi: b.hi,
    });
  }

  if (group.chart && group.structure === structure) {
    group.chart.explorerBands = group.bands;
    group.chart.setData(data);
    return;
  }
  if (group.chart) { group.chart.destroy(); group.chart = null; delete window.explorerCharts[group.key]; }
  group.structure = structure;
  group.chartEl.textContent = '';
  if (!plan.length) {
    group.chartEl.append(el('p', { class: 'hint empty' }, 'No channel selected.'));
    return;
  }

  const scales = { x: { time: false } };
  units.forEach((u) => {
    const key = scaleOf(u);
    scales[key] = { auto: true, range: (_u, min, max) => bandRange(group.bands, key, min, max) };
  });
  const axes = [{ label: 't [s]', values: tickValues }];
  units.forEach((u, i) => {
    // One channel's name with its unit, else the unit alone (the legend names the lines),
    // so the label fits the axis.
    const names = selected.filter((c) => (c.unit || '') === u).map((c) => c.name);
    const label = names.length === 1 ? withUnit(names[0], u) : (u ? `[${u}]` : '');
    axes.push({
      scale: scaleOf(u),
      label,
      values: tickValues,
      side: i % 2 === 0 ? 3 : 1,
      size: 64,
      grid: { show: i === 0 },
    });
  });
  const series = [{ label: 't [s]', value: legendValue }];
  for (const s of plan) {
    const base = { scale: scaleOf(s.c.unit || ''), value: legendValue, spanGaps: true, points: { show: false } };
    if (s.kind === 'pred') series.push({ ...base, label: s.c.name, stroke: s.c.color, width: 1.6 });
    else if (s.kind === 'solver') series.push({ ...base, label: `${s.c.name} (solver)`, stroke: s.c.color, width: 1.4, dash: [6, 4] });
    else series.push({ ...base, label: `${s.c.name} (A)`, stroke: PIN_COLOR, width: 1 });
  }
  const opts = {
    width: chartWidth(group.chartEl),
    height: group.height,
    scales,
    axes,
    series,
    cursor: { sync: { key: SYNC_KEY }, drag: { x: true, y: false } },
    legend: { live: true },
    hooks: { drawAxes: [(u) => drawBands(u, group.bands, u.data[0])] },
  };
  group.chart = new uPlot(opts, data, group.chartEl);
  group.chart.explorerBands = group.bands;
  window.explorerCharts[group.key] = group.chart;
}

/** The y range of scale `key`: the data's and every band's on it, padded as uPlot pads. */
export function bandRange(bands, key, min, max) {
  let lo = min;
  let hi = max;
  for (const b of bands || []) {
    if (b.scale !== key) continue;
    for (const v of b.lo) if (v != null && Number.isFinite(v) && (lo == null || v < lo)) lo = v;
    for (const v of b.hi) if (v != null && Number.isFinite(v) && (hi == null || v > hi)) hi = v;
  }
  if (lo == null || hi == null) return [min, max];
  return uPlot.rangeNum(lo, hi, 0.1, true);
}

/** Fills each band `{lo, hi, fill, scale}` between its two curves over `x`. */
export function drawBands(u, bands, x) {
  if (!bands || !bands.length || !x) return;
  const ctx = u.ctx;
  const { left, top, width, height } = u.bbox;
  ctx.save();
  ctx.beginPath();
  ctx.rect(left, top, width, height);
  ctx.clip();
  for (const b of bands) {
    const n = Math.min(x.length, b.lo.length, b.hi.length);
    if (n < 2) continue;
    ctx.beginPath();
    for (let i = 0; i < n; i++) {
      const px = u.valToPos(x[i], 'x', true);
      const py = u.valToPos(b.hi[i], b.scale, true);
      if (i === 0) ctx.moveTo(px, py); else ctx.lineTo(px, py);
    }
    for (let i = n - 1; i >= 0; i--) {
      ctx.lineTo(u.valToPos(x[i], 'x', true), u.valToPos(b.lo[i], b.scale, true));
    }
    ctx.closePath();
    ctx.fillStyle = b.fill;
    ctx.fill();
  }
  ctx.restore();
}

export function renderAllCharts(st) {
  for (const g of st.groups) renderChart(st, g);
  renderChannelErrors(st);
}

function renderChannelErrors(st) {
  const solve = solveOverlay(st);
  const pred = st.prediction && st.prediction.answer;
  for (const g of st.groups) {
    for (const label of g.section.querySelectorAll('.channel')) {
      const span = $('.channel-error', label);
      const e = solve && solve.errors ? solve.errors[label.dataset.channel] : null;
      span.textContent = solve && e != null ? fmtPercent(e) : '';
      span.title = solve && e != null ? 'relative L2 error of the surrogate vs the solver' : '';
      span.classList.toggle('large-error', !!solve && isLarge(e));
      const f = solve ? channelInside(pred, solve, label.dataset.channel) : null;
      if (f != null) {
        span.append(insideMark(f === 1, f === 1 ? 'inside the band' : `${fmtPercent(f)} inside the band`));
        span.title += '; whether the solver curve lies inside the band';
      }
    }
  }
}

/** Keeps every chart (and the sweep's, `sweepChart()`) as wide as its card. */
export function watchResize(st, sweepChart) {
  let pending = false;
  const resizeAll = () => {
    pending = false;
    for (const g of st.groups) {
      if (g.chart) {
        const w = chartWidth(g.chartEl);
        if (w !== g.chart.width) g.chart.setSize({ width: w, height: g.height });
      }
    }
    const sweep = sweepChart();
    if (sweep) {
      const w = chartWidth($('#sweep-chart'));
      if (w !== sweep.width) sweep.setSize({ width: w, height: SWEEP_HEIGHT });
    }
  };
  const schedule = () => {
    if (!pending) { pending = true; requestAnimationFrame(resizeAll); }
  };
  window.addEventListener('resize', schedule);
  if (window.ResizeObserver) new ResizeObserver(schedule).observe($('.results'));
}
