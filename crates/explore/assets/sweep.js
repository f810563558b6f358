/*
 * The sweep: one parameter across a range through the surrogate (POST /api/sweep, and a few
 * points through the solver) against one index, with its limit, its band (with a calibration)
 * and the values outside the training range shaded. A model without sampled parameters (or
 * without indices) has no sweep.
 */
import { $, el } from './dom.js';
import { fmt, percent, withAlpha, withUnit, limitText } from './format.js';
import { runsOf } from './series.js';
import { requestBody } from './state.js';
import { postRetryingOnce } from './api.js';
import { showError, clearError, setBusy, bumpCounter, nextFrame, publishState } from './ui.js';
import { BAND_ALPHA, SWEEP_HEIGHT, bandRange, chartWidth, drawBands, legendValue, tickValues } from './charts.js';
import { buildStudyStart } from './studies-start.js';

const SWEEP_COLOR = '#1f77b4';
let chart = null;

/** The sweep's uPlot chart, once drawn. */
export const sweepChart = () => chart;

/**
 * Marks the sweep's chart as the last sweep answered, not the one asked for (it failed):
 * greyed with a note until a sweep is answered again.
 */
function markSweepStale(st, stale) {
  const on = stale && !!st.sweep;
  $('#sweep').classList.toggle('stale', on);
  $('#sweep-stale').hidden = !on;
}

const paramMeta = (st, name) => st.summary.parameters.find((p) => p.name === name);

export function buildSweep(st) {
  const summary = st.summary;
  if (!summary.indices.length || !summary.parameters.length) {
    $('#sweep').hidden = true;
    return;
  }
  const paramSel = $('#sweep-param');
  const indexSel = $('#sweep-index');
  paramSel.replaceChildren(...summary.parameters.map((p) =>
    el('option', { value: p.name }, withUnit(p.name, p.unit))));
  indexSel.replaceChildren(...summary.indices.map((i) =>
    el('option', { value: i.name }, withUnit(i.name, i.unit))));
  const withLimit = summary.indices.find((i) => i.limit);
  if (withLimit) indexSel.value = withLimit.name;
  const maxSteps = (summary.limits && summary.limits.sweep_max_designs) || 400;
  $('#sweep-steps').max = String(maxSteps);
  $('#sweep-steps').value = String(Math.min(100, maxSteps));

  const resetRange = () => {
    const p = paramMeta(st, paramSel.value);
    $('#sweep-from').value = String(p.min);
    $('#sweep-to').value = String(p.max);
  };
  resetRange();
  paramSel.addEventListener('change', resetRange);
  // The answer holds every index: switching the index only redraws.
  indexSel.addEventListener('change', () => { if (st.sweep) renderSweep(st); });
  $('#run-sweep').addEventListener('click', () => runSweep(st));
  buildStudyStart(st);
}

export async function runSweep(st) {
  const button = $('#run-sweep');
  const status = $('#sweep-status');
  const body = {
    ...requestBody(st),
    parameter: $('#sweep-param').value,
    from: $('#sweep-from').valueAsNumber,
    to: $('#sweep-to').valueAsNumber,
    steps: $('#sweep-steps').valueAsNumber,
    solve_points: $('#sweep-solve-points').valueAsNumber,
  };
  for (const k of ['from', 'to', 'steps', 'solve_points']) {
    if (!Number.isFinite(body[k])) {
      showError({ message: `${k} must be a number`, field: k }, 'Sweep');
      return;
    }
  }
  button.disabled = true;
  button.classList.add('busy');
  status.textContent = body.solve_points > 0 ? 'sweeping (with the solver)…' : 'sweeping…';
  setBusy(st, 'sweeping', +1);
  try {
    const answer = await postRetryingOnce('/api/sweep', body, {
      onWait: (left) => { status.textContent = left ? `solver busy, retrying in ${left} s` : 'retrying…'; },
    });
    await nextFrame();
    st.sweep = answer;
    st.sweepRequest = body;
    publishState(st);
    clearError();
    markSweepStale(st, false);
    renderSweep(st);
    status.textContent = answer.elapsed_ms != null
      ? `${answer.values.length} designs in ${fmt(answer.elapsed_ms, 3)} ms` : '';
    await Promise.resolve();
    bumpCounter(st, 'sweeps');
  } catch (err) {
    status.textContent = '';
    showError(err, 'Sweep');
    markSweepStale(st, true);
  } finally {
    button.disabled = false;
    button.classList.remove('busy');
    setBusy(st, 'sweeping', -1);
  }
}

/** uPlot draw hook: shades the parameter values outside the training range. */
function outsideBands(values, outside) {
  const runs = runsOf(outside || []);
  return (u) => {
    if (!runs.length) return;
    const ctx = u.ctx;
    const { top, height, left, width } = u.bbox;
    const half = values.length > 1 ? Math.abs(values[1] - values[0]) / 2 : 0;
    ctx.save();
    ctx.fillStyle = 'rgba(245, 158, 11, 0.16)';
    for (const [a, b] of runs) {
      const lo = Math.min(values[a], values[b]) - half;
      const hi = Math.max(values[a], values[b]) + half;
      let x0 = u.valToPos(lo, 'x', true);
      let x1 = u.valToPos(hi, 'x', true);
      x0 = Math.max(left, Math.min(left + width, x0));
      x1 = Math.max(left, Math.min(left + width, x1));
      ctx.fillRect(x0, top, x1 - x0, height);
    }
    ctx.restore();
  };
}

function renderSweep(st) {
  const sw = st.sweep;
  const node = $('#sweep-chart');
  if (!sw) return;
  const indexName = $('#sweep-index').value;
  const meta = st.summary.indices.find((i) => i.name === indexName);
  const p = paramMeta(st, sw.parameter) || { name: sw.parameter, unit: '' };
  const values = sw.values || [];
  const surrogate = (sw.indices && sw.indices[indexName]) || values.map(() => null);
  const solved = (sw.solved || []).filter((s) => s.indices && s.indices[indexName] != null);

  // One ascending x for all series: the sweep's values joined with the solver's points.
  const descending = values.length > 1 && values[0] > values[values.length - 1];
  const tables = [descending ? [[...values].reverse(), [...surrogate].reverse()] : [values, surrogate]];
  if (solved.length) {
    const sorted = [...solved].sort((a, b) => a.value - b.value);
    tables.push([sorted.map((s) => s.value), sorted.map((s) => s.indices[indexName])]);
  }
  const joined = tables.length > 1 ? uPlot.join(tables) : tables[0];
  const data = [joined[0], joined[1]];
  const iv = sw.intervals && sw.intervals[indexName];
  const sweepBands = iv ? [{
    channel: indexName, color: SWEEP_COLOR, fill: withAlpha(SWEEP_COLOR, BAND_ALPHA), scale: 'y',
    lo: iv.lo, hi: iv.hi, x: values,
  }] : [];

  const series = [
    { label: withUnit(p.name, p.unit), value: legendValue },
    { label: 'surrogate', stroke: SWEEP_COLOR, width: 2, spanGaps: true, points: { show: false }, value: legendValue },
  ];
  if (solved.length) {
    // Markers only: no line between the solver's points.
    series.push({
      label: 'solver', stroke: '#d62728', fill: '#d62728', width: 0,
      paths: () => null, points: { show: true, size: 9, stroke: '#d62728', fill: '#d62728' }, value: legendValue,
    });
    data.push(joined[2]);
  }
  if (meta && meta.limit) {
    series.push({
      label: `limit (${limitText(meta.limit)})`, stroke: '#b91c1c', width: 1.2, dash: [8, 5],
      points: { show: false }, value: legendValue,
    });
    data.push(data[0].map(() => meta.limit.value));
  }
  const opts = {
    width: chartWidth(node),
    height: SWEEP_HEIGHT,
    scales: { x: { time: false }, y: { auto: true, range: (_u, min, max) => bandRange(sweepBands, 'y', min, max) } },
    axes: [
      { label: withUnit(p.name, p.unit), values: tickValues },
      {
        label: withUnit(indexName, meta ? meta.unit : ''), values: tickValues, size: 64,
        labelFont: '600 12px system-ui, sans-serif',
      },
    ],
    series,
    cursor: { drag: { x: true, y: false } },
    hooks: {
      drawClear: [outsideBands(values, sw.outside)],
      drawAxes: [(u) => drawBands(u, sweepBands, values)],
    },
  };
  if (chart) chart.destroy();
  node.textContent = '';
  chart = new uPlot(opts, data, node);
  chart.explorerBands = sweepBands;
  window.explorerCharts.sweep = chart;
  $('#sweep-band-hint').textContent = iv
    ? `Band: the surrogate's ${percent(sw.coverage)} interval of ${indexName} at every design.`
    : (sw.no_intervals ? 'No error bar on the sweep.' : '');
  const nOutside = (sw.outside || []).filter(Boolean).length;
  $('#sweep-hint').textContent = `The other parameters stay at the design of the request. `
    + (nOutside ? `Shaded: ${nOutside} of ${values.length} values outside the training range.`
      : 'All values inside the training range.');
}
