/*
 * The indices table: per index the surrogate's value, its interval and three-valued verdict
 * (with a calibration), its limit and pass/fail, the solver's value with the surrogate's error
 * and whether it lies inside the interval (after "Solve exactly"), and design A's value with
 * B − A (when pinned); above it the headline verdict and the intervals' verdict (verdicts.js).
 */
import { $, el } from './dom.js';
import { fmt, fmtSigned, fmtPercent, percent, limitText } from './format.js';
import { indexInside } from './series.js';
import { LARGE_ERROR, isLarge, headline, intervalVerdict } from './verdicts.js';
import { solveOverlay } from './state.js';

function badge(pass) {
  if (pass === true) return el('span', { class: 'badge pass' }, 'pass');
  if (pass === false) return el('span', { class: 'badge fail' }, 'fail');
  return el('span', { class: 'badge none' }, 'no limit');
}

/** The three-valued verdict of an interval against its limit. */
function verdictBadge(verdict) {
  if (!verdict) return el('span', { class: 'badge none' }, 'no limit');
  const title = {
    pass: 'the whole interval meets the limit',
    uncertain: 'the interval straddles the limit: send the design to the solver',
    fail: 'the whole interval is over the limit',
  }[verdict] || '';
  return el('span', { class: `badge ${verdict}`, title, dataset: { verdict } }, verdict);
}

/** ✓ inside / ✗ outside mark of a solver value against an interval or band. */
export function insideMark(inside, text) {
  return el('span', { class: `inside-mark ${inside ? 'in' : 'out'}`, dataset: { inside: String(inside) } },
    inside ? `✓ ${text || 'inside'}` : `✗ ${text || 'outside'}`);
}

export function renderIndices(st) {
  const table = $('#indices');
  const pred = st.prediction && st.prediction.answer;
  const solve = solveOverlay(st);
  const pinned = st.pinned;
  const byName = (list) => Object.fromEntries((list || []).map((x) => [x.name, x]));
  const predBy = byName(pred && pred.indices);
  const solveBy = byName(solve && solve.indices);
  const pinBy = byName(pinned && pinned.prediction.indices);

  const calibrated = !!(pred && pred.coverage != null);
  const head = ['index', 'unit', 'surrogate'];
  if (calibrated) head.push(`interval (${percent(pred.coverage)})`);
  head.push('limit', 'status');
  if (calibrated) head.push('verdict');
  if (solve) head.push('solver', 'error %');
  if (pinned) head.push('A', 'Δ (B − A)');
  const thead = el('tr', {}, ...head.map((h, j) =>
    el('th', { class: j >= 2 && h !== 'status' && h !== 'verdict' ? 'num' : '' }, h)));
  table.tHead.replaceChildren(thead);

  const rows = st.summary.indices.map((meta) => {
    const p = predBy[meta.name];
    const cells = [
      el('td', { class: 'name', title: meta.definition || '' }, meta.name),
      el('td', { class: 'unit' }, meta.unit || ''),
      el('td', { class: 'value num' }, p ? fmt(p.value) : '—'),
    ];
    if (calibrated) {
      cells.push(el('td', { class: 'interval num' },
        p && p.lo != null ? `[${fmt(p.lo)}, ${fmt(p.hi)}]` : '—'));
    }
    cells.push(
      el('td', { class: 'limit num' }, limitText(meta.limit)),
      el('td', { class: 'status', title: 'the point value against the limit' }, badge(p ? p.pass : null)));
    if (calibrated) {
      cells.push(el('td', { class: 'verdict-cell' }, verdictBadge(p ? p.verdict : null)));
    }
    if (solve) {
      const s = solveBy[meta.name];
      const e = solve.index_errors ? solve.index_errors[meta.name] : null;
      const inside = calibrated ? indexInside(pred, solve, meta.name) : null;
      cells.push(
        el('td', { class: 'solver num' }, s ? fmt(s.value) : '—',
          s && s.pass != null ? ' ' : null, s && s.pass != null ? badge(s.pass) : null,
          inside != null ? insideMark(inside) : null),
        el('td', { class: `error num${isLarge(e) ? ' large-error' : ''}`,
          title: isLarge(e) ? `above ${fmtPercent(LARGE_ERROR)}: the surrogate is off here` : '' },
        fmtPercent(e, true)));
    }
    if (pinned) {
      const a = pinBy[meta.name];
      const d = p && a && Number.isFinite(p.value) && Number.isFinite(a.value) ? p.value - a.value : null;
      const rel = d != null && a.value !== 0 ? d / Math.abs(a.value) : null;
      cells.push(
        el('td', { class: 'a num' }, a ? fmt(a.value) : '—'),
        el('td', { class: 'delta num', title: rel != null ? fmtPercent(rel, true) : '' },
          d != null ? fmtSigned(d) : '—'));
    }
    return el('tr', { dataset: { index: meta.name } }, ...cells);
  });
  table.tBodies[0].replaceChildren(...rows);

  // The headline verdict: the solver's once it answered this design, the surrogate's beside.
  const verdict = $('#verdict');
  verdict.className = 'verdict';
  const h = headline(pred, solve);
  verdict.textContent = h ? h.text : '';
  if (h) verdict.classList.add(h.tone);
  verdict.dataset.pass = h ? String(h.pass) : '';
  verdict.dataset.source = h ? h.source : '';

  // The three-valued verdict of the intervals.
  const iv = $('#interval-verdict');
  iv.className = 'verdict';
  const v = intervalVerdict(pred, st.summary.calibration_note);
  iv.textContent = v ? v.text : '';
  iv.title = v ? v.title : '';
  iv.dataset.verdict = v ? v.verdict : '';
  if (v && pred.coverage == null) iv.classList.add('none');
  else if (v && v.verdict) iv.classList.add(v.verdict);
  if (v && v.extrapolated) iv.append(el('span', { class: 'extrapolated' }, '(extrapolated: no coverage claim)'));
}
