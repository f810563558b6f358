/*
 * pino-mbd "pipeline at a glance" — the read-only page /pipeline of `explore`.
 *
 * Polls GET /api/pipeline every 2 s and shows: the units of the pipeline file with their
 * state (fresh, stale, never run, submitted, running; a colour per state), the detail and a
 * progress bar while a unit reports progress; Table 4 of the latest `evaluate` (its first row
 * is the header); the evaluate plots as images from GET /api/pipeline/plot/NAME.
 *
 * Test hooks: body[data-state] = loading | idle (after each answer drawn), body[data-polls]
 * counts the answers drawn, window.pipelineState = the last answer.
 * An ES module (dom.js's helpers); plain ES2020, no inline scripts, no eval.
 */
import { $, el, fmt, poll } from './dom.js';

(() => {
  const POLL_MS = 2000;
  let lastTable4 = '';
  let lastPlots = '';
  window.pipelineState = null;

  /** `never run` -> `state-never-run`; unknown states get `state-other` too. */
  function stateClass(state) {
    const known = ['fresh', 'stale', 'never run', 'submitted', 'running'];
    const slug = String(state || '').toLowerCase().replace(/[^a-z0-9]+/g, '-');
    return known.includes(String(state)) ? `state state-${slug}` : `state state-other state-${slug}`;
  }

  function progressCell(progress) {
    if (!progress) return el('td', { class: 'progress-cell' }, '');
    const { done, total, message } = progress;
    const bar = el('progress', { max: String(total > 0 ? total : 1), value: String(done || 0) });
    const text = `${done ?? 0}/${total ?? '?'}${message ? ` · ${message}` : ''}`;
    return el('td', { class: 'progress-cell' },
      el('div', { class: 'progress' }, bar, el('span', { class: 'progress-text' }, text)));
  }

  function renderUnits(units) {
    const rows = (units || []).map((u) => el('tr', { dataset: { unit: u.key, state: u.state } },
      el('td', { class: 'name' }, u.key),
      el('td', {}, u.stage || ''),
      el('td', {}, el('span', { class: stateClass(u.state) }, u.state)),
      el('td', { class: 'detail' }, u.detail || ''),
      progressCell(u.progress)));
    $('#units tbody').replaceChildren(...rows);
    $('#units-empty').hidden = rows.length > 0;
  }

  function renderTable4(table4) {
    const key = JSON.stringify(table4 || null);
    if (key === lastTable4) return;
    lastTable4 = key;
    const table = $('#table4');
    if (!table4 || !table4.length) {
      table.tHead.replaceChildren();
      table.tBodies[0].replaceChildren();
      $('#table4-empty').hidden = false;
      return;
    }
    $('#table4-empty').hidden = true;
    const [header, ...rows] = table4;
    // A value not computed (NaN, written `NaN` or `nan`) is a missing number, shown as `—`.
    const missing = (c) => typeof c === 'string' && /^[-+]?nan$/i.test(c.trim());
    const isNum = (c) => typeof c === 'number'
      || (typeof c === 'string' && c.trim() !== '' && (missing(c) || !Number.isNaN(Number(c))));
    // A column is right-aligned when every row holds a number there (the first is a label).
    const numeric = header.map((_, j) => j > 0 && rows.length > 0 && rows.every((r) => isNum(r[j])));
    // A header breaks only after `_`, `-` or `/`, never inside a word.
    const breakable = (h) => String(h ?? '').split(/(?<=[_/-])/)
      .flatMap((part, i) => (i ? [el('wbr'), part] : [part]));
    table.tHead.replaceChildren(el('tr', {}, ...header.map((h, j) =>
      el('th', { class: numeric[j] ? 'num' : '' }, ...breakable(h)))));
    // Numbers to 4 significant digits (the file's exact value as the cell's tooltip).
    const cell = (c, j) => {
      if (numeric[j] && missing(c)) return el('td', { class: 'num missing', title: 'not computed (NaN)' }, '—');
      return numeric[j]
        ? el('td', { class: 'num', title: String(c) }, fmt(Number(c)))
        : el('td', {}, c == null ? '' : c);
    };
    table.tBodies[0].replaceChildren(...rows.map((r) => el('tr', {}, ...r.map(cell))));
  }

  function renderPlots(plots) {
    const key = JSON.stringify(plots || []);
    if (key === lastPlots) return;
    lastPlots = key;
    const host = $('#plots');
    host.replaceChildren(...(plots || []).map((name) => {
      const src = `/api/pipeline/plot/${encodeURIComponent(name)}`;
      return el('figure', {},
        el('a', { href: src, target: '_blank', rel: 'noopener' }, el('img', { src, alt: name, loading: 'lazy' })),
        el('figcaption', {}, name));
    }));
    $('#plots-empty').hidden = (plots || []).length > 0;
  }

  poll('/api/pipeline', POLL_MS, (answer) => {
    window.pipelineState = answer;
    $('#pipeline-file').textContent = answer.file || '—';
    renderUnits(answer.units);
    renderTable4(answer.evaluate ? answer.evaluate.table4 : null);
    renderPlots(answer.evaluate ? answer.evaluate.plots : []);
  });
})();
