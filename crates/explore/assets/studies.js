/*
 * pino-mbd "studies" — the page /studies of `explore` (docs/explore.md, docs/studies.md).
 *
 * Polls GET /api/studies every 2 s and shows every study: the pipeline's (the units of its
 * `study` stage, with their state) and those started from the explorer's sweep view (running,
 * with its progress and a Cancel button, finished, failed or cancelled; the one-line summary
 * with its `code` as code). Each study with files gets a card: its Markdown report (summary.md,
 * rendered with DOM nodes only: headings, paragraphs, lists, tables, `code`), its plots, the
 * table a reader opens next (summary.csv, sobol.csv or optimum.csv, folded), its declaration
 * as YAML (ready for the pipeline file) and links to every file
 * (GET /api/studies/SOURCE/NAME/FILE).
 *
 * Test hooks: body[data-state] = loading | idle (after each answer drawn), body[data-polls]
 * counts the answers drawn, window.studiesState = the last answer; a running study's row and
 * card hold `progress` and `button.cancel-study`.
 * An ES module (dom.js's helpers); plain ES2020, no inline scripts, no eval, no innerHTML.
 */
import { $, el, poll } from './dom.js';
import { api } from './api.js';

(() => {
  const POLL_MS = 2000;
  const drawn = new Map(); // card id -> the JSON it was drawn from
  window.studiesState = null;

  const cardId = (s) => `study-${s.source}-${s.name}`;
  const fileUrl = (s, f) => `/api/studies/${encodeURIComponent(s.source)}/${encodeURIComponent(s.name)}/${encodeURIComponent(f)}`;

  /** `never run` -> `state-never-run`; the started studies' states share the units' colours. */
  function stateClass(state) {
    const colour = { fresh: 'fresh', finished: 'fresh', stale: 'stale', failed: 'stale',
      'never run': 'never-run', submitted: 'submitted', running: 'running', cancelled: 'never-run' }[state];
    return colour ? `state state-${colour}` : 'state state-other';
  }

  /** Inline Markdown: `code` and **bold**; everything else is text. */
  function inline(text) {
    const out = [];
    const re = /(`[^`]*`|\*\*[^*]+\*\*)/g;
    let last = 0;
    for (const m of text.matchAll(re)) {
      if (m.index > last) out.push(text.slice(last, m.index));
      const t = m[0];
      out.push(t.startsWith('`') ? el('code', {}, t.slice(1, -1)) : el('strong', {}, t.slice(2, -2)));
      last = m.index + t.length;
    }
    if (last < text.length) out.push(text.slice(last));
    return out;
  }

  /** The cells of a Markdown table row (`\|` is a literal bar). */
  function cells(line) {
    const parts = [];
    let cur = '';
    const body = line.trim().replace(/^\|/, '').replace(/\|$/, '');
    for (let i = 0; i < body.length; i += 1) {
      if (body[i] === '\\' && body[i + 1] === '|') { cur += '|'; i += 1; } else if (body[i] === '|') { parts.push(cur.trim()); cur = ''; } else cur += body[i];
    }
    parts.push(cur.trim());
    return parts;
  }

  const isNumberCell = (c) => /^[-+]?(\d|\.\d)/.test(c) && !Number.isNaN(parseFloat(c));

  /** The Markdown the study stage writes, as DOM nodes. */
  function renderMarkdown(text) {
    const nodes = [];
    const lines = String(text || '').split('\n');
    let i = 0;
    while (i < lines.length) {
      const line = lines[i];
      if (!line.trim()) { i += 1; continue; }
      const h = /^(#{1,4})\s+(.*)$/.exec(line);
      if (h) { nodes.push(el(`h${Math.min(h[1].length + 2, 6)}`, {}, ...inline(h[2]))); i += 1; continue; }
      if (line.trim().startsWith('|')) {
        const rows = [];
        while (i < lines.length && lines[i].trim().startsWith('|')) { rows.push(cells(lines[i])); i += 1; }
        const [head, ...rest] = rows;
        const body = rest.filter((r) => !r.every((c) => /^:?-{3,}:?$/.test(c)));
        nodes.push(el('div', { class: 'table-wrap' }, el('table', { class: 'data-table md-table' },
          el('thead', {}, el('tr', {}, ...head.map((c) => el('th', {}, ...inline(c))))),
          el('tbody', {}, ...body.map((r) => el('tr', {}, ...r.map((c) =>
            el('td', { class: isNumberCell(c) ? 'num' : '' }, ...inline(c)))))))));
        continue;
      }
      if (/^\s*[-*]\s+/.test(line)) {
        const items = [];
        while (i < lines.length && /^\s*[-*]\s+/.test(lines[i])) { items.push(lines[i].replace(/^\s*[-*]\s+/, '')); i += 1; }
        nodes.push(el('ul', {}, ...items.map((t) => el('li', {}, ...inline(t)))));
        continue;
      }
      const para = [];
      while (i < lines.length && lines[i].trim() && !/^(#{1,4}\s|\s*\||\s*[-*]\s)/.test(lines[i])) { para.push(lines[i]); i += 1; }
      nodes.push(el('p', {}, ...inline(para.join(' '))));
    }
    return nodes;
  }

  function renderTable(table) {
    const [header, ...rows] = table.rows;
    const numeric = header.map((_, j) => rows.length > 0 && rows.every((r) => r[j] === '' || isNumberCell(r[j] || '')));
    return el('div', { class: 'table-wrap study-table' }, el('table', { class: 'data-table', dataset: { file: table.file } },
      el('thead', {}, el('tr', {}, ...header.map((h, j) => el('th', { class: numeric[j] ? 'num' : '' }, h)))),
      el('tbody', {}, ...rows.map((r) => el('tr', {}, ...r.map((c, j) =>
        el('td', { class: numeric[j] ? 'num' : '' }, formatCell(c))))))));
  }

  /** A number of a CSV shown with 4 significant digits (the file keeps them all). */
  function formatCell(c) {
    if (!isNumberCell(c) || /^\d+$/.test(c)) return c;
    const x = Number(c);
    return Number.isFinite(x) ? String(Number(x.toPrecision(4))) : c;
  }

  /** Asks the server to cancel the running started study `name`. */
  async function cancelStudy(button, name) {
    button.disabled = true;
    button.textContent = 'cancelling…';
    try {
      await api('POST', '/api/studies/cancel', { name });
    } catch (err) {
      $('.error-message').textContent = `Cancelling ${name}: ${err.message || err}`;
      $('#error').hidden = false;
      button.disabled = false;
      button.textContent = 'Cancel';
    }
  }

  /** A running started study's progress bar and Cancel button (null for any other). */
  function progressOf(s) {
    if (s.state !== 'running' || !s.progress) return null;
    const p = s.progress;
    const bar = el('progress', { max: String(Math.max(1, p.total)), value: String(p.done) });
    const cancel = el('button', { type: 'button', class: 'btn small cancel-study', disabled: p.cancelling },
      p.cancelling ? 'cancelling…' : 'Cancel');
    cancel.addEventListener('click', () => cancelStudy(cancel, s.name));
    return el('div', { class: 'progress study-progress' }, bar,
      el('span', { class: 'progress-text' }, `${p.done}/${p.total}`), s.source === 'explorer' ? cancel : null);
  }

  function renderCard(s) {
    const children = [
      el('div', { class: 'card-head' },
        el('h2', {}, `${s.name} `, el('span', { class: 'subtitle' }, `${s.kind} · ${s.source}`)),
        el('span', { class: stateClass(s.state) }, s.state)),
      s.detail ? el('p', { class: 'hint study-detail' }, ...inline(s.detail)) : null,
      progressOf(s),
    ];
    if (s.summary_md) children.push(el('div', { class: 'study-report' }, ...renderMarkdown(s.summary_md)));
    if (s.plots.length) {
      children.push(el('div', { class: 'plots' }, ...s.plots.map((p) => {
        const src = fileUrl(s, p);
        return el('figure', {},
          el('a', { href: src, target: '_blank', rel: 'noopener' }, el('img', { src, alt: `${s.name}: ${p}`, loading: 'lazy' })),
          el('figcaption', {}, p));
      })));
    }
    if (s.table) {
      children.push(el('details', { class: 'study-declaration' },
        el('summary', {}, `Table ${s.table.file} (${s.table.rows.length - 1} rows, every digit in the file)`),
        renderTable(s.table)));
    }
    children.push(el('details', { class: 'study-declaration' },
      el('summary', {}, s.source === 'explorer' ? 'Declaration (add it to the pipeline file’s study matrix to rerun it there)' : 'Declaration'),
      el('pre', {}, s.declaration)));
    if (s.files.length) {
      children.push(el('p', { class: 'hint study-files' }, 'Files: ',
        ...s.files.flatMap((f, k) => [k ? ' · ' : '', el('a', { href: fileUrl(s, f) }, f)])));
    }
    return el('section', { class: 'card study-card', id: cardId(s), dataset: { source: s.source, name: s.name, state: s.state } }, ...children);
  }

  function render(answer) {
    const all = [...(answer.explorer || []), ...(answer.pipeline || [])];
    $('#study-list tbody').replaceChildren(...all.map((s) => el('tr', { dataset: { source: s.source, name: s.name, state: s.state } },
      el('td', { class: 'name' }, el('a', { href: `#${cardId(s)}` }, s.name)),
      el('td', {}, s.kind),
      el('td', {}, s.source === 'explorer' ? 'explorer (sweep view)' : 'pipeline'),
      el('td', {}, el('span', { class: stateClass(s.state) }, s.state)),
      el('td', { class: 'detail' }, ...inline(s.detail || ''), progressOf(s)))));
    $('#studies-empty').hidden = all.length > 0;
    const host = $('#studies');
    const keep = new Set();
    for (const s of all) {
      const id = cardId(s);
      keep.add(id);
      const key = JSON.stringify(s);
      if (drawn.get(id) === key) continue;
      drawn.set(id, key);
      const card = renderCard(s);
      const old = document.getElementById(id);
      if (old) old.replaceWith(card); else host.append(card);
    }
    for (const id of [...drawn.keys()]) {
      if (!keep.has(id)) { drawn.delete(id); const n = document.getElementById(id); if (n) n.remove(); }
    }
  }

  poll('/api/studies', POLL_MS, (answer, polls) => {
    window.studiesState = answer;
    $('#pipeline-file').textContent = answer.file || '—';
    $('#study-dir').textContent = answer.dir || '—';
    render(answer);
    if (polls === 0 && window.location.hash) {
      const target = document.getElementById(decodeURIComponent(window.location.hash.slice(1)));
      if (target) target.scrollIntoView();
    }
  });
})();
