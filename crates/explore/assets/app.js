/*
 * pino-mbd design explorer — the browser side of `explore` (served as /assets/app.js).
 *
 * What it does:
 *   - reads the model summary (GET /api/model) and builds everything from it: one row per
 *     design parameter (slider over the training range + number field), the excitation
 *     chooser, one chart section per channel group, the indices table and the sweep controls.
 *     Nothing here is written for one particular system.
 *   - on every design or excitation change asks the surrogate (POST /api/predict) and redraws
 *     the curves (uPlot, cursors synchronised across the charts) and the indices with their
 *     limits; parameters outside the training range are flagged.
 *   - "Solve exactly" (POST /api/solve) overlays the exact solver's curves (dashed) and shows
 *     the surrogate's errors; "Pin as A" keeps a design to compare the following ones with;
 *     the sweep (POST /api/sweep) plots one index against one parameter; downloads fetch the
 *     design YAML and the curves (CSV / Parquet); "Start study" (POST /api/studies) runs a
 *     Monte Carlo or Sobol study of the swept parameter (and one more) and follows it until it
 *     ends, with a link to the Studies page (/studies) that shows it.
 *   - with a calibration (summary.calibration, docs/uncertainty.md): every plotted channel is
 *     drawn with its band (shaded, the channel's colour), every index with its interval and
 *     three-valued verdict (pass / uncertain / fail), the sweep's index curve with its band;
 *     the level selector (0.8 / 0.9 / 0.95, the levels the calibration cannot support
 *     disabled with the reason) re-requests the prediction and the sweep; after a solve,
 *     each channel and index says whether the solver's answer lies inside.
 *
 * Hooks for browser tests:
 *   window.explorerState   = {summary, design, excitation, prediction, solve, sweep}
 *   window.explorerMetrics = {predictToRedrawMs: [...]}   (change event -> redraw done, ms)
 *   window.explorerCharts  = {GROUP: uPlot, sweep: uPlot}  (what is plotted: `u.data`, the
 *                            series labels `u.series[i].label`: CHANNEL, `CHANNEL (solver)`, `CHANNEL (A)`;
 *                            the shaded bands `u.explorerBands`: [{channel, color, fill, lo, hi}])
 *   window.explorerBandAlpha: the opacity of a band's fill (its colour over white is known)
 *   body[data-state]       = loading | idle | predicting | solving | sweeping
 *   body[data-predictions], body[data-solves], body[data-sweeps]: counters bumped after drawing
 *   body[data-study], body[data-study-state]: the study last started from the sweep view and,
 *     once it ended, `finished` or `failed`
 *
 * Plain ES2020, no framework, no build step; the only dependency is the vendored uPlot
 * (global `uPlot`, see VENDORED.md). No inline scripts, no eval (CSP `script-src 'self'`).
 */
'use strict';

(() => {
  // ---------------------------------------------------------------------------------------
  // Constants and state
  // ---------------------------------------------------------------------------------------

  /** Chart sections, in page order; a channel's `group` picks its section. */
  const GROUPS = [
    { key: 'displacement', title: 'Displacements', height: 230 },
    { key: 'velocity', title: 'Velocities', height: 230 },
    { key: 'acceleration', title: 'Accelerations', height: 230 },
    { key: 'force', title: 'Forces', height: 230 },
    { key: 'excitation', title: 'Excitation', height: 200 },
  ];
  const DEFAULT_SELECTED_PER_GROUP = 2;
  const SWEEP_HEIGHT = 320;
  const SYNC_KEY = 'pino-explorer';
  // Series colours (the first ten of a group; channelColor makes more).
  const PALETTE = ['#1f77b4', '#d62728', '#2ca02c', '#9467bd', '#ff7f0e',
    '#17becf', '#8c564b', '#e377c2', '#7f7f7f', '#bcbd22'];
  const PIN_COLOR = '#9aa0a6';

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
  function channelColor(i) {
    if (i < PALETTE.length) return PALETTE[i];
    const j = i - PALETTE.length;
    return hslHex((15 + j * 137.508) % 360, 0.6, j % 2 === 0 ? 0.36 : 0.52);
  }
  // A surrogate error (relative, of an index or a channel's L2) above this stands out.
  const LARGE_ERROR = 0.10;
  // Opacity of the bands' fill (the channel's colour); the sweep's band is the surrogate's.
  const BAND_ALPHA = 0.22;
  const SWEEP_COLOR = '#1f77b4';
  window.explorerBandAlpha = BAND_ALPHA;

  /** Everything the page knows; `window.explorerState` is a view of the API part of it. */
  const st = {
    summary: null,
    design: {},            // {NAME: number}, what the next request sends
    excitation: null,      // request excitation object, or null (system without profiles)
    prediction: null,      // last predict answer drawn
    predictionRev: -1,     // design revision the prediction belongs to
    solve: null,           // last solve answer
    solveRev: -1,          // design revision the solve belongs to (overlay only if current)
    sweep: null,           // last sweep answer
    sweepRequest: null,    // the request of the last sweep (parameter, index limits...)
    pinned: null,          // {design, excitation, prediction, indices}
    rev: 0,                // bumped on every design / excitation change
    predictSeq: 0,
    predictAbort: null,
    busy: { predicting: 0, solving: 0, sweeping: 0 },
    counters: { predictions: 0, solves: 0, sweeps: 0 },
    groups: [],            // [{key, title, height, channels: [meta], selected: Set, el..., chart}]
    sweepChart: null,
    coverage: null,        // level of the intervals sent with every request (null: no calibration)
  };

  window.explorerMetrics = { predictToRedrawMs: [] };
  window.explorerCharts = {};
  window.explorerState = {
    summary: null, design: null, excitation: null, prediction: null, solve: null, sweep: null,
    coverage: null,
  };

  function publishState() {
    const s = window.explorerState;
    s.summary = st.summary;
    s.design = { ...st.design };
    s.excitation = st.excitation ? { ...st.excitation } : null;
    s.prediction = st.prediction;
    s.solve = st.solve;
    s.sweep = st.sweep;
    s.coverage = st.coverage;
    s.stale = !!st.stale;
  }

  // ---------------------------------------------------------------------------------------
  // Small helpers
  // ---------------------------------------------------------------------------------------

  const { $, el, fmt } = window.pinoDom;

  function fmtSigned(v, digits = 4) {
    if (v == null || !Number.isFinite(v)) return fmt(v, digits);
    return (v > 0 ? '+' : '') + fmt(v, digits);
  }

  function fmtPercent(fraction, signed = false) {
    if (fraction == null || !Number.isFinite(fraction)) return '—';
    const p = fraction * 100;
    const a = Math.abs(p);
    const s = a >= 100 ? p.toFixed(0) : a >= 10 ? p.toFixed(1) : p.toFixed(2);
    return `${signed && p > 0 ? '+' : ''}${s} %`;
  }

  const withUnit = (name, unit) => (unit ? `${name} [${unit}]` : name);

  const nextFrame = () => new Promise((resolve) => requestAnimationFrame(() => resolve()));
  const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

  function paramMeta(name) {
    return st.summary.parameters.find((p) => p.name === name);
  }

  function indexMeta(name) {
    return st.summary.indices.find((i) => i.name === name);
  }

  function limitText(limit) {
    if (!limit) return '—';
    return `${limit.kind === 'min' ? '≥' : '≤'} ${fmt(limit.value)}`;
  }

  // ---------------------------------------------------------------------------------------
  // API access and errors
  // ---------------------------------------------------------------------------------------

  class ApiError extends Error {
    constructor(status, payload, retryAfter) {
      const msg = (payload && payload.error) || `HTTP ${status}`;
      super(msg);
      this.name = 'ApiError';
      this.status = status;
      this.field = payload && payload.field;
      this.allowed = payload && payload.allowed;
      this.retryAfterS = retryAfter;
    }
  }

  /** fetch wrapper: JSON in, JSON (or a Blob) out; non-2xx answers throw ApiError. */
  async function api(method, path, body, { signal, as = 'json' } = {}) {
    const init = { method, credentials: 'same-origin', headers: {}, signal };
    if (body !== undefined) {
      init.headers['Content-Type'] = 'application/json';
      init.body = JSON.stringify(body);
    }
    const res = await fetch(path, init);
    if (!res.ok) {
      let payload = null;
      try { payload = await res.json(); } catch (_) { /* not JSON */ }
      let retry = Number(res.headers.get('Retry-After'));
      if (!Number.isFinite(retry) || res.headers.get('Retry-After') === null) {
        retry = payload && Number.isFinite(payload.retry_after_s) ? payload.retry_after_s : null;
      }
      if (!payload || !payload.error) {
        const why = {
          403: 'refused: this host or token is not allowed',
          404: 'no such endpoint',
          413: 'request too large',
          429: 'solver busy',
          500: 'server fault',
        }[res.status];
        payload = { ...(payload || {}), error: why ? `${why} (HTTP ${res.status})` : `HTTP ${res.status} ${res.statusText}` };
      }
      throw new ApiError(res.status, payload, retry);
    }
    return as === 'blob' ? res.blob() : res.json();
  }

  /** Shows an error in the #error box; `context` says what was being done. */
  function showError(err, context) {
    if (err && err.name === 'AbortError') return;
    const box = $('#error');
    $('.error-title', box).textContent = context ? `${context} failed:` : 'Error:';
    $('.error-message', box).textContent = (err && err.message) || String(err);
    $('.error-field', box).textContent = err && err.field ? `field: ${err.field}` : '';
    $('.error-allowed', box).textContent = err && err.allowed ? `allowed: ${err.allowed}` : '';
    box.dataset.field = (err && err.field) || '';
    box.hidden = false;
    // Mark the parameter row a `design.NAME` field names.
    document.querySelectorAll('.param.invalid').forEach((r) => r.classList.remove('invalid'));
    const m = err && typeof err.field === 'string' && err.field.match(/^design\.(.+)$/);
    if (m) {
      const row = paramRow(m[1]);
      if (row) row.classList.add('invalid');
    }
    if (err && !(err instanceof ApiError)) console.warn(err);
  }

  /**
   * Marks the results as those of an older design (an input was refused): greyed, with the
   * "out of date" banner, until a prediction of the design on screen arrives.
   */
  function markStale(stale) {
    st.stale = stale;
    document.body.classList.toggle('stale', stale);
    $('#stale-banner').hidden = !stale;
    publishState();
  }

  function clearError() {
    const box = $('#error');
    box.hidden = true;
    box.dataset.field = '';
    document.querySelectorAll('.param.invalid').forEach((r) => r.classList.remove('invalid'));
  }

  function setBusy(kind, delta) {
    st.busy[kind] = Math.max(0, st.busy[kind] + delta);
    const b = st.busy;
    document.body.dataset.state = b.solving ? 'solving' : b.sweeping ? 'sweeping'
      : b.predicting ? 'predicting' : 'idle';
  }

  function bumpCounter(name) {
    st.counters[name] += 1;
    document.body.dataset[name] = String(st.counters[name]);
  }

  /** The body of predict / solve / download requests. */
  function requestBody() {
    const body = { design: { ...st.design } };
    if (st.excitation) body.excitation = { ...st.excitation };
    if (st.coverage != null) {
      body.coverage = st.coverage;
      // Only the plotted channels' bands travel (the excitations have none).
      body.bands = st.groups.filter((g) => g.key !== 'excitation')
        .flatMap((g) => g.channels.filter((c) => g.selected.has(c.name)).map((c) => c.name));
    }
    return body;
  }

  /** `#rrggbb` at opacity `alpha` as a CSS colour. */
  function withAlpha(hex, alpha) {
    const n = parseInt(hex.slice(1), 16);
    return `rgba(${(n >> 16) & 255}, ${(n >> 8) & 255}, ${n & 255}, ${alpha})`;
  }

  const percent = (level) => `${Number((level * 100).toPrecision(4))} %`;

  // ---------------------------------------------------------------------------------------
  // Header
  // ---------------------------------------------------------------------------------------

  function renderHeader(summary) {
    document.title = `${summary.system} — design explorer`;
    $('#system-name').textContent = summary.system;
    const m = summary.model || {};
    $('#model-dir').textContent = m.dir || '—';
    $('#model-dir').title = m.dir || '';
    $('#model-algorithm').textContent = m.algorithm != null ? String(m.algorithm) : '—';
    const id = $('#model-identity');
    id.textContent = m.identity ? m.identity.slice(0, 12) : '—';
    id.title = m.identity || '';
  }

  // ---------------------------------------------------------------------------------------
  // Level of the intervals
  // ---------------------------------------------------------------------------------------

  /** The level selector: the calibration's reported levels, unsupported ones disabled. */
  function buildCoverage(summary) {
    const select = $('#coverage');
    const note = $('#calibration-note');
    const cal = summary.calibration;
    select.textContent = '';
    if (!cal) {
      select.append(el('option', { value: '' }, 'none'));
      select.disabled = true;
      st.coverage = null;
      note.textContent = 'no error bar';
      note.title = summary.calibration_note || 'no calibration';
      $('#coverage-box').title = summary.calibration_note || 'no calibration';
      document.body.dataset.calibrated = 'false';
      return;
    }
    for (const l of cal.levels || []) {
      select.append(el('option', {
        value: String(l.level), disabled: !l.supported,
        title: l.supported ? `${percent(l.level)} interval` : `not supported: ${l.why}`,
      }, l.supported ? percent(l.level) : `${percent(l.level)} (needs more calibration samples)`));
    }
    const supported = (cal.levels || []).filter((l) => l.supported).map((l) => l.level);
    if (!supported.length && cal.max_coverage > 0) {
      // A calibration too small for every listed level: its highest, n / (n + 1).
      select.append(el('option', { value: String(cal.max_coverage) }, `${percent(cal.max_coverage)} (n / (n + 1))`));
      supported.push(cal.max_coverage);
    }
    const def = supported.includes(cal.default_coverage) ? cal.default_coverage
      : supported.length ? supported[supported.length - 1] : null;
    st.coverage = def;
    select.disabled = def == null;
    if (def != null) select.value = String(def);
    note.textContent = `calibration: n = ${cal.n}, ${cal.normaliser}`;
    note.title = cal.file || '';
    document.body.dataset.calibrated = 'true';
    select.addEventListener('change', () => {
      const t0 = performance.now();
      const v = Number(select.value);
      if (!Number.isFinite(v)) return;
      st.coverage = v;
      publishState();
      predict(t0);
      if (st.sweep) runSweep();
    });
  }

  // ---------------------------------------------------------------------------------------
  // Parameter panel
  // ---------------------------------------------------------------------------------------

  function paramRow(name) {
    return [...document.querySelectorAll('#params .param')].find((r) => r.dataset.param === name);
  }

  const isOutside = (p, v) => v < p.min || v > p.max;

  /** Rounds a slider-derived value so the number field shows what is sent. */
  const roundForDisplay = (v) => Number(v.toPrecision(6));

  /** The slider step of parameter `p`: a thousandth of its training range. */
  const sliderStep = (p) => (p.max - p.min) / 1000;

  /**
   * `v` as parameter `p`'s number field shows it when the design comes from elsewhere (a test
   * sample): rounded to the decimals of the slider's step, so the field does not overflow.
   */
  function fieldValue(p, v) {
    const step = sliderStep(p);
    if (!(step > 0) || !Number.isFinite(v)) return roundForDisplay(v);
    const decimals = Math.min(12, Math.max(0, Math.ceil(-Math.log10(step))));
    return Number(v.toFixed(decimals));
  }

  function buildParams(summary) {
    const host = $('#params');
    host.textContent = '';
    summary.parameters.forEach((p, i) => {
      const id = `param-${i}`;
      const slider = el('input', {
        type: 'range', id: `${id}-range`, min: String(p.min), max: String(p.max),
        step: sliderStep(p) > 0 ? String(sliderStep(p)) : 'any', 'aria-label': `${p.name} slider`,
      });
      const number = el('input', { type: 'number', id, step: 'any', 'aria-label': `${p.name} value` });
      const flag = el('span', { class: 'outside-flag', hidden: true }, 'outside training range');
      const row = el('div', { class: 'param', dataset: { param: p.name } },
        el('div', { class: 'param-head' },
          el('label', { for: id, class: 'param-name' }, p.name),
          el('span', { class: 'unit' }, p.unit || ''),
          flag),
        el('div', { class: 'param-controls' }, slider, number),
        el('div', { class: 'param-range' },
          `${fmt(p.min)} … ${fmt(p.max)}`,
          el('span', { class: 'nominal' }, ` · nominal ${fmt(p.nominal)}`)));

      // Dragging updates the number only; releasing (change) predicts.
      slider.addEventListener('input', () => {
        const v = roundForDisplay(Number(slider.value));
        number.value = String(v);
        markOutside(p, v);
      });
      slider.addEventListener('change', () => {
        const t0 = performance.now();
        const v = roundForDisplay(Number(slider.value));
        number.value = String(v);
        setParam(p.name, v);
        predict(t0);
      });
      number.addEventListener('change', () => {
        const t0 = performance.now();
        const v = number.valueAsNumber;
        if (!Number.isFinite(v)) {
          showError({ message: `parameter \`${p.name}\` must be a finite number`,
            field: `design.${p.name}`, allowed: 'a finite number' }, 'Input');
          markStale(true);
          return;
        }
        slider.value = String(Math.min(p.max, Math.max(p.min, v)));
        setParam(p.name, v);
        predict(t0);
      });
      host.append(row);
    });
  }

  function markOutside(p, v) {
    const row = paramRow(p.name);
    if (!row) return;
    const out = isOutside(p, v);
    row.classList.toggle('outside', out);
    $('input[type=number]', row).classList.toggle('outside', out);
    $('.outside-flag', row).hidden = !out;
  }

  function setParam(name, v) {
    offerUndo(null);
    const row = paramRow(name);
    if (row) $('input[type=number]', row).title = '';
    st.design[name] = v;
    st.rev += 1;
    publishState();
    renderPinInfo();
  }

  /**
   * Writes a whole design into the panel (sliders, numbers, flags). The design keeps the exact
   * values; a number field shows its value rounded to the slider's step when that differs,
   * with the exact value as its tooltip.
   */
  function setDesign(design) {
    for (const p of st.summary.parameters) {
      const v = design[p.name] != null ? design[p.name] : p.nominal;
      st.design[p.name] = v;
      const row = paramRow(p.name);
      $('input[type=range]', row).value = String(Math.min(p.max, Math.max(p.min, v)));
      const number = $('input[type=number]', row);
      const shown = fieldValue(p, v);
      number.value = String(shown);
      number.title = shown === v ? '' : `exactly ${v}`;
      markOutside(p, v);
    }
    st.rev += 1;
    publishState();
    renderPinInfo();
  }

  function nominalDesign() {
    const d = {};
    for (const p of st.summary.parameters) d[p.name] = p.nominal;
    return d;
  }

  /** The banner and the per-row flags from a predict answer's `outside`. */
  function renderOutside(outside) {
    const names = (outside || []).map((o) => o.name);
    const banner = $('#outside-banner');
    if (names.length) {
      banner.textContent = `outside training range: ${names.join(', ')}`;
      banner.title = (outside || []).map((o) =>
        `${o.name} = ${fmt(o.value)} (trained on ${fmt(o.min)} … ${fmt(o.max)})`).join('\n');
      banner.hidden = false;
    } else {
      banner.textContent = '';
      banner.hidden = true;
    }
    for (const p of st.summary.parameters) {
      const row = paramRow(p.name);
      const out = names.includes(p.name);
      row.classList.toggle('outside', out);
      $('input[type=number]', row).classList.toggle('outside', out);
      $('.outside-flag', row).hidden = !out;
    }
  }

  // ---------------------------------------------------------------------------------------
  // Excitation chooser
  // ---------------------------------------------------------------------------------------

  function buildExcitation(summary) {
    const ex = summary.excitation || {};
    const box = $('#excitation-box');
    if (!ex.generated_profiles || ex.generated_profiles.length === 0) {
      box.hidden = true;
      st.excitation = null;
      return;
    }
    const select = $('#excitation');
    select.textContent = '';
    for (const s of ex.test_samples || []) {
      select.append(el('option', { value: `test:${s.sample_id}` }, `test sample ${s.sample_id}`));
    }
    select.append(el('option', { value: 'seed' }, 'generated from seed'));
    $('#excitation-hint').textContent = `profiles: ${ex.generated_profiles.join(', ')}`;

    const def = ex.default || ((ex.test_samples || []).length
      ? { kind: 'test', sample_id: ex.test_samples[0].sample_id }
      : { kind: 'seed', seed: 1, id: 0 });
    if (def.kind === 'test' && (ex.test_samples || []).some((s) => s.sample_id === def.sample_id)) {
      select.value = `test:${def.sample_id}`;
    } else {
      select.value = 'seed';
      if (def.kind === 'seed') {
        $('#excitation-seed').value = String(def.seed ?? 1);
        $('#excitation-id').value = String(def.id ?? 0);
      }
    }
    readExcitation();

    select.addEventListener('change', () => {
      const t0 = performance.now();
      readExcitation();
      const sample = selectedTestSample();
      if (sample) {
        const previous = { ...st.design };
        setDesign({ ...nominalDesign(), ...(sample.design || {}) });
        offerUndo(previous, `Undo: back to the design before test sample ${sample.sample_id}`);
      }
      st.rev += 1;
      predict(t0);
    });
    for (const id of ['#excitation-seed', '#excitation-id']) {
      $(id).addEventListener('change', () => {
        const t0 = performance.now();
        if (!readExcitation()) return;
        st.rev += 1;
        predict(t0);
      });
    }
  }

  /**
   * Offers to put `previous` back (the design a test sample's replaced), or withdraws the
   * offer (`previous` null: the user has changed the design since).
   */
  function offerUndo(previous, text) {
    const button = $('#undo-design');
    st.undoDesign = previous;
    button.hidden = !previous;
    if (previous) button.textContent = text;
  }

  function undoDesign() {
    const previous = st.undoDesign;
    if (!previous) return;
    const t0 = performance.now();
    setDesign(previous);
    offerUndo(null);
    predict(t0);
  }

  function selectedTestSample() {
    const v = $('#excitation').value;
    if (!v.startsWith('test:')) return null;
    const id = Number(v.slice(5));
    return (st.summary.excitation.test_samples || []).find((s) => s.sample_id === id) || null;
  }

  /** Reads the chooser into st.excitation; false (and an error shown) when invalid. */
  function readExcitation() {
    const v = $('#excitation').value;
    const seedFields = $('#seed-fields');
    if (v.startsWith('test:')) {
      seedFields.hidden = true;
      st.excitation = { kind: 'test', sample_id: Number(v.slice(5)) };
    } else {
      seedFields.hidden = false;
      const seed = $('#excitation-seed').valueAsNumber;
      const id = $('#excitation-id').valueAsNumber;
      for (const [name, x] of [['seed', seed], ['id', id]]) {
        if (!Number.isInteger(x) || x < 0) {
          showError({ message: `${name} must be a non-negative integer`,
            field: `excitation.${name}`, allowed: 'a non-negative integer' }, 'Input');
          return false;
        }
      }
      st.excitation = { kind: 'seed', seed, id };
    }
    publishState();
    return true;
  }

  // ---------------------------------------------------------------------------------------
  // Predict
  // ---------------------------------------------------------------------------------------

  /**
   * Asks the surrogate for the current design and redraws. `t0` (performance.now() of the
   * user's change event) is recorded in explorerMetrics once the redraw is done. A newer
   * request supersedes (aborts) an older one still in flight.
   */
  async function predict(t0 = null) {
    if (st.predictAbort) st.predictAbort.abort();
    const abort = new AbortController();
    st.predictAbort = abort;
    const seq = ++st.predictSeq;
    const rev = st.rev;
    setBusy('predicting', +1);
    $('#predict-status').textContent = 'predicting…';
    try {
      const answer = await api('POST', '/api/predict', requestBody(), { signal: abort.signal });
      if (seq !== st.predictSeq) return;
      await nextFrame();
      if (seq !== st.predictSeq) return;
      st.prediction = answer;
      st.predictionRev = rev;
      // The solver overlay belongs to the design it was solved for.
      if (st.solve && st.solveRev !== rev) clearSolve();
      clearError();
      markStale(false);
      renderOutside(answer.outside);
      renderIndices();
      renderAllCharts();
      renderPinInfo();
      $('#pin').disabled = false;
      $('#predict-status').textContent = answer.elapsed_ms != null
        ? `surrogate: ${fmt(answer.elapsed_ms, 3)} ms` : '';
      // uPlot commits its redraw in a microtask queued by setData; measure after it.
      await Promise.resolve();
      if (t0 != null) window.explorerMetrics.predictToRedrawMs.push(performance.now() - t0);
      bumpCounter('predictions');
    } catch (err) {
      if (seq === st.predictSeq) {
        $('#predict-status').textContent = '';
        showError(err, 'Prediction');
        // A refused input leaves the last answer on screen, marked as another design's.
        if (err instanceof ApiError && err.status === 400) markStale(true);
      }
    } finally {
      if (st.predictAbort === abort) st.predictAbort = null;
      setBusy('predicting', -1);
    }
  }

  // ---------------------------------------------------------------------------------------
  // Indices table
  // ---------------------------------------------------------------------------------------

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

  /** Whether a relative error stands out (above LARGE_ERROR). */
  function isLarge(e) {
    return e != null && Number.isFinite(e) && Math.abs(e) > LARGE_ERROR;
  }

  /** ✓ inside / ✗ outside mark of a solver value against an interval. */
  function insideMark(inside, text) {
    return el('span', { class: `inside-mark ${inside ? 'in' : 'out'}`, dataset: { inside: String(inside) } },
      inside ? `✓ ${text || 'inside'}` : `✗ ${text || 'outside'}`);
  }

  /** Whether the solve's index value lies inside the prediction's interval (null: unknown). */
  function indexInside(pred, solve, name) {
    const p = (pred.indices || []).find((x) => x.name === name);
    const s = (solve.indices || []).find((x) => x.name === name);
    if (!p || !s || p.lo == null || p.hi == null) return null;
    if (solve.coverage === pred.coverage && solve.index_inside && name in solve.index_inside) {
      return solve.index_inside[name];
    }
    return p.lo <= s.value && s.value <= p.hi;
  }

  function renderIndices() {
    const table = $('#indices');
    const pred = st.prediction;
    const solve = solveOverlay();
    const pinned = st.pinned;
    const byName = (list) => Object.fromEntries((list || []).map((x) => [x.name, x]));
    const predBy = byName(pred && pred.indices);
    const solveBy = byName(solve && solve.indices);
    const pinBy = byName(pinned && pinned.indices);

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
    const said = (answer) => (answer.pass ? 'all limits met' : `fails ${(answer.failed || []).join(', ')}`);
    const extrapolated = pred && ((pred.outside || []).length > 0 || pred.extrapolated);
    if (!pred) {
      verdict.textContent = '';
    } else if (solve) {
      verdict.textContent = `solver: ${said(solve)}; surrogate: ${said(pred)}${extrapolated ? ' (extrapolated)' : ''}`;
      verdict.classList.add(solve.pass ? 'pass' : 'fail');
    } else {
      verdict.textContent = `${said(pred)}${extrapolated ? ' (surrogate, extrapolated)' : ''}`;
      verdict.classList.add(pred.pass ? 'pass' : 'fail');
    }
    verdict.dataset.pass = !pred ? '' : String(!!(solve || pred).pass);
    verdict.dataset.source = !pred ? '' : solve ? 'solver' : 'surrogate';

    // The three-valued verdict of the intervals.
    const iv = $('#interval-verdict');
    iv.className = 'verdict';
    iv.textContent = '';
    iv.title = '';
    iv.dataset.verdict = '';
    if (pred && pred.coverage != null) {
      const v = pred.verdict;
      const what = {
        pass: 'pass', uncertain: 'uncertain: send to the solver', fail: 'fail',
      }[v] || 'no limit';
      iv.textContent = `at ${percent(pred.coverage)}: ${what}`;
      if (v) iv.classList.add(v);
      iv.dataset.verdict = v || '';
      if (pred.extrapolated) {
        iv.append(el('span', { class: 'extrapolated' }, '(extrapolated: no coverage claim)'));
      }
      iv.title = 'the calibrated intervals against the limits (docs/uncertainty.md)';
    } else if (pred) {
      iv.textContent = 'no error bar';
      iv.classList.add('none');
      iv.title = pred.no_intervals || (st.summary && st.summary.calibration_note) || '';
    }
  }

  // ---------------------------------------------------------------------------------------
  // Response charts
  // ---------------------------------------------------------------------------------------

  function buildChartSections(summary) {
    const host = $('#charts');
    host.textContent = '';
    st.groups = [];
    for (const g of GROUPS) {
      // Copies of the summary's channels with a colour each, distinct within the group (the
      // summary stays as received).
      const channels = summary.channels.filter((c) => c.group === g.key)
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
          renderChart(group);
          // A newly plotted channel's band comes with the next prediction.
          const pred = st.prediction;
          if (box.checked && st.coverage != null && g.key !== 'excitation' && pred
            && !(pred.bands && pred.bands[c.name])) predict();
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
  function tickValues(u, splits, axisIdx) {
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

  function legendValue(_u, v) {
    return v == null ? '—' : fmt(v, 4);
  }

  /** y series of `y` at x positions `x` onto `xRef`, linearly interpolated (null outside). */
  function alignTo(xRef, x, y) {
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

  /** The solve answer if it belongs to the current design, else null. */
  function solveOverlay() {
    return st.solve && st.solveRev === st.predictionRev ? st.solve : null;
  }

  function chartWidth(node) {
    return Math.max(240, Math.floor(node.clientWidth || node.parentElement.clientWidth || 600));
  }

  /** Redraws one section's chart: rebuilt when its series change, else just setData. */
  function renderChart(group) {
    const pred = st.prediction;
    if (!pred) return;
    const solve = solveOverlay();
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
  function bandRange(bands, key, min, max) {
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
  function drawBands(u, bands, x) {
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

  function renderAllCharts() {
    for (const g of st.groups) renderChart(g);
    renderChannelErrors();
  }

  function renderChannelErrors() {
    const solve = solveOverlay();
    for (const g of st.groups) {
      for (const label of g.section.querySelectorAll('.channel')) {
        const span = $('.channel-error', label);
        const e = solve && solve.errors ? solve.errors[label.dataset.channel] : null;
        span.textContent = solve && e != null ? fmtPercent(e) : '';
        span.title = solve && e != null ? 'relative L2 error of the surrogate vs the solver' : '';
        span.classList.toggle('large-error', !!solve && isLarge(e));
        const f = solve ? channelInside(st.prediction, solve, label.dataset.channel) : null;
        if (f != null) {
          span.append(insideMark(f === 1, f === 1 ? 'inside the band' : `${fmtPercent(f)} inside the band`));
          span.title += '; whether the solver curve lies inside the band';
        }
      }
    }
  }

  /** The fraction of the solver curve's rows inside the prediction's band (null: no band). */
  function channelInside(pred, solve, name) {
    const b = pred && pred.bands && pred.bands[name];
    if (!b) return null;
    const given = solve.inside && solve.inside[name];
    if (given && solve.coverage === pred.coverage) return given.fraction_inside;
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

  /** Keeps every chart as wide as its card. */
  function watchResize() {
    let pending = false;
    const resizeAll = () => {
      pending = false;
      for (const g of st.groups) {
        if (g.chart) {
          const w = chartWidth(g.chartEl);
          if (w !== g.chart.width) g.chart.setSize({ width: w, height: g.height });
        }
      }
      if (st.sweepChart) {
        const node = $('#sweep-chart');
        const w = chartWidth(node);
        if (w !== st.sweepChart.width) st.sweepChart.setSize({ width: w, height: SWEEP_HEIGHT });
      }
    };
    const schedule = () => {
      if (!pending) { pending = true; requestAnimationFrame(resizeAll); }
    };
    window.addEventListener('resize', schedule);
    if (window.ResizeObserver) new ResizeObserver(schedule).observe($('.results'));
  }

  // ---------------------------------------------------------------------------------------
  // Solve exactly
  // ---------------------------------------------------------------------------------------

  function clearSolve() {
    st.solve = null;
    st.solveRev = -1;
    $('#solve-status').textContent = '';
    publishState();
  }

  /** Waits `seconds`, counting down in #solve-status. */
  async function countdown(seconds, node) {
    const end = performance.now() + seconds * 1000;
    for (;;) {
      const left = Math.ceil((end - performance.now()) / 1000);
      if (left <= 0) break;
      node.textContent = `solver busy, retrying in ${left} s`;
      await sleep(Math.min(1000, end - performance.now()));
    }
  }

  /** POST with one retry after a 429 (solver busy), the wait shown in `statusNode`. */
  async function postRetryingOnce(path, body, statusNode) {
    try {
      return await api('POST', path, body);
    } catch (err) {
      if (!(err instanceof ApiError) || err.status !== 429) throw err;
      const wait = err.retryAfterS != null && err.retryAfterS >= 0 ? err.retryAfterS : 1;
      await countdown(wait, statusNode);
      statusNode.textContent = 'retrying…';
      return api('POST', path, body);
    }
  }

  async function solve() {
    const button = $('#solve');
    const status = $('#solve-status');
    const rev = st.rev;
    button.disabled = true;
    button.classList.add('busy');
    status.textContent = 'solving…';
    setBusy('solving', +1);
    try {
      const answer = await postRetryingOnce('/api/solve', requestBody(), status);
      if (rev !== st.rev) {
        status.textContent = 'the design changed while solving; solve again';
        return;
      }
      // The prediction for this design may still be on its way: wait for it.
      while (st.predictionRev !== rev && st.busy.predicting) await sleep(20);
      await nextFrame();
      st.solve = answer;
      st.solveRev = rev;
      publishState();
      clearError();
      renderIndices();
      renderAllCharts();
      status.textContent = answer.solve_ms != null ? `solver: ${fmt(answer.solve_ms, 3)} ms` : 'solved';
      await Promise.resolve();
      bumpCounter('solves');
    } catch (err) {
      status.textContent = '';
      showError(err, 'Solve');
    } finally {
      button.disabled = false;
      button.classList.remove('busy');
      setBusy('solving', -1);
    }
  }

  // ---------------------------------------------------------------------------------------
  // Pin A / compare B
  // ---------------------------------------------------------------------------------------

  function pin() {
    if (!st.prediction) return;
    st.pinned = {
      design: { ...st.design },
      excitation: st.excitation ? { ...st.excitation } : null,
      prediction: st.prediction,
      indices: st.prediction.indices,
    };
    $('#unpin').disabled = false;
    document.body.dataset.pinned = 'true';
    renderPinInfo();
    renderIndices();
    renderAllCharts();
  }

  function unpin() {
    st.pinned = null;
    $('#unpin').disabled = true;
    delete document.body.dataset.pinned;
    renderPinInfo();
    renderIndices();
    renderAllCharts();
  }

  function renderPinInfo() {
    const info = $('#pin-info');
    const a = st.pinned;
    if (!a) {
      info.textContent = 'Pin the current design as A to compare the next ones (B) with it.';
      return;
    }
    const diff = st.summary.parameters.filter((p) => a.design[p.name] !== st.design[p.name]);
    const exSame = JSON.stringify(a.excitation) === JSON.stringify(st.excitation);
    const parts = diff.map((p) => `${p.name} ${fmt(a.design[p.name])} → ${fmt(st.design[p.name])}`);
    if (!exSame) parts.push('excitation');
    info.textContent = parts.length ? `B differs from A in: ${parts.join('; ')}` : 'B is the same design as A.';
  }

  // ---------------------------------------------------------------------------------------
  // Sweep
  // ---------------------------------------------------------------------------------------

  function buildSweep(summary) {
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
      const p = paramMeta(paramSel.value);
      $('#sweep-from').value = String(p.min);
      $('#sweep-to').value = String(p.max);
    };
    resetRange();
    paramSel.addEventListener('change', resetRange);
    // The answer holds every index: switching the index only redraws.
    indexSel.addEventListener('change', () => { if (st.sweep) renderSweep(); });
    $('#run-sweep').addEventListener('click', runSweep);
    if (!summary.indices.length) $('#sweep').hidden = true;
    buildStudyStart(summary);
  }

  // ---------------------------------------------------------------------------------------
  // A study started from the sweep view (POST /api/studies; shown on /studies)
  // ---------------------------------------------------------------------------------------

  function buildStudyStart(summary) {
    const limits = summary.studies;
    if (!limits) { $('#study-start').hidden = true; return; }
    const second = $('#study-param2');
    const fill = () => {
      const first = $('#sweep-param').value;
      const keep = second.value;
      second.replaceChildren(el('option', { value: '' }, '— none —'),
        ...summary.parameters.filter((p) => p.name !== first).map((p) =>
          el('option', { value: p.name }, withUnit(p.name, p.unit))));
      second.value = keep && keep !== first ? keep : '';
      second.dispatchEvent(new Event('change'));
    };
    second.addEventListener('change', () => {
      const on = second.value !== '';
      for (const id of ['#study-from2', '#study-to2']) $(id).disabled = !on;
      if (on) {
        const p = paramMeta(second.value);
        $('#study-from2').value = String(p.min);
        $('#study-to2').value = String(p.max);
      } else {
        $('#study-from2').value = '';
        $('#study-to2').value = '';
      }
    });
    const kind = $('#study-kind');
    const setKind = () => {
      const k = kind.value;
      $('#study-n').max = String(limits.max_n[k]);
      $('#study-n').value = String(limits.default_n[k]);
      $('#study-n-label').textContent = k === 'sensitivity' ? 'rows (power of 2)' : 'designs';
      $('#study-solver-check').max = String(limits.max_solver_check);
    };
    kind.addEventListener('change', setKind);
    $('#sweep-param').addEventListener('change', fill);
    setKind();
    fill();
    $('#start-study').addEventListener('click', startStudy);
  }

  async function startStudy() {
    const button = $('#start-study');
    const status = $('#study-status');
    const parameters = [{
      name: $('#sweep-param').value,
      from: $('#sweep-from').valueAsNumber,
      to: $('#sweep-to').valueAsNumber,
    }];
    if ($('#study-param2').value) {
      parameters.push({
        name: $('#study-param2').value,
        from: $('#study-from2').valueAsNumber,
        to: $('#study-to2').valueAsNumber,
      });
    }
    const body = {
      design: { ...st.design },
      kind: $('#study-kind').value,
      parameters,
      n: $('#study-n').valueAsNumber,
      solver_check: $('#study-solver-check').valueAsNumber,
    };
    if (st.coverage != null) body.coverage = st.coverage;
    button.disabled = true;
    status.textContent = 'starting…';
    try {
      const started = await api('POST', '/api/studies', body);
      clearError();
      document.body.dataset.study = started.name;
      await followStudy(started.name, status);
    } catch (err) {
      status.textContent = '';
      showError(err, 'Study');
    } finally {
      button.disabled = false;
    }
  }

  /** Polls the Studies list until the started study `name` is finished or failed. */
  async function followStudy(name, status) {
    const link = () => el('a', { href: `/studies#study-explorer-${name}` }, 'on the Studies page');
    for (;;) {
      const answer = await api('GET', '/api/studies');
      const s = (answer.explorer || []).find((x) => x.name === name);
      if (!s) throw new Error(`the study ${name} is no longer listed`);
      if (s.state === 'running') {
        status.replaceChildren(`${name}: ${s.detail} — `, link());
        await sleep(1000);
        continue;
      }
      status.replaceChildren(`${name} ${s.state}: ${s.detail} — `, link());
      document.body.dataset.studyState = s.state;
      return;
    }
  }

  async function runSweep() {
    const button = $('#run-sweep');
    const status = $('#sweep-status');
    const body = {
      ...requestBody(),
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
    setBusy('sweeping', +1);
    try {
      const answer = await postRetryingOnce('/api/sweep', body, status);
      await nextFrame();
      st.sweep = answer;
      st.sweepRequest = body;
      publishState();
      clearError();
      renderSweep();
      status.textContent = answer.elapsed_ms != null
        ? `${answer.values.length} designs in ${fmt(answer.elapsed_ms, 3)} ms` : '';
      await Promise.resolve();
      bumpCounter('sweeps');
    } catch (err) {
      status.textContent = '';
      showError(err, 'Sweep');
    } finally {
      button.disabled = false;
      button.classList.remove('busy');
      setBusy('sweeping', -1);
    }
  }

  /** Runs of consecutive `true` in `flags`, as [first, last] index pairs. */
  function runsOf(flags) {
    const runs = [];
    let start = -1;
    flags.forEach((f, i) => {
      if (f && start < 0) start = i;
      if (!f && start >= 0) { runs.push([start, i - 1]); start = -1; }
    });
    if (start >= 0) runs.push([start, flags.length - 1]);
    return runs;
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

  function renderSweep() {
    const sw = st.sweep;
    const node = $('#sweep-chart');
    if (!sw) return;
    const indexName = $('#sweep-index').value;
    const meta = indexMeta(indexName);
    const p = paramMeta(sw.parameter) || { name: sw.parameter, unit: '' };
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
    if (st.sweepChart) st.sweepChart.destroy();
    node.textContent = '';
    st.sweepChart = new uPlot(opts, data, node);
    st.sweepChart.explorerBands = sweepBands;
    window.explorerCharts.sweep = st.sweepChart;
    $('#sweep-band-hint').textContent = iv
      ? `Band: the surrogate's ${percent(sw.coverage)} interval of ${indexName} at every design.`
      : (sw.no_intervals ? 'No error bar on the sweep.' : '');
    const nOutside = (sw.outside || []).filter(Boolean).length;
    $('#sweep-hint').textContent = `The other parameters stay at the design of the request. `
      + (nOutside ? `Shaded: ${nOutside} of ${values.length} values outside the training range.`
        : 'All values inside the training range.');
  }

  // ---------------------------------------------------------------------------------------
  // Downloads
  // ---------------------------------------------------------------------------------------

  async function download(button, path, filename) {
    button.disabled = true;
    try {
      const blob = await api('POST', path, requestBody(), { as: 'blob' });
      const url = URL.createObjectURL(blob);
      const a = el('a', { href: url, download: filename, class: 'hidden-link' });
      document.body.append(a);
      a.click();
      a.remove();
      setTimeout(() => URL.revokeObjectURL(url), 10000);
    } catch (err) {
      showError(err, `Download of ${filename}`);
    } finally {
      button.disabled = false;
    }
  }

  // ---------------------------------------------------------------------------------------
  // Start
  // ---------------------------------------------------------------------------------------

  function wireButtons() {
    $('#error-dismiss').addEventListener('click', clearError);
    $('#reset').addEventListener('click', () => {
      const t0 = performance.now();
      offerUndo(null);
      setDesign(nominalDesign());
      predict(t0);
    });
    $('#solve').addEventListener('click', solve);
    $('#undo-design').addEventListener('click', undoDesign);
    $('#pin').addEventListener('click', pin);
    $('#unpin').addEventListener('click', unpin);
    $('#download-design').addEventListener('click', (e) =>
      download(e.currentTarget, '/api/download/design', 'design.yaml'));
    $('#download-csv').addEventListener('click', (e) =>
      download(e.currentTarget, '/api/download/curves?format=csv', 'curves.csv'));
    $('#download-parquet').addEventListener('click', (e) =>
      download(e.currentTarget, '/api/download/curves?format=parquet', 'curves.parquet'));
  }

  async function start() {
    document.body.dataset.predictions = '0';
    document.body.dataset.solves = '0';
    document.body.dataset.sweeps = '0';
    wireButtons();
    let summary;
    try {
      summary = await api('GET', '/api/model');
    } catch (err) {
      showError(err, 'Loading the model');
      document.body.dataset.state = 'idle';
      return;
    }
    st.summary = summary;
    renderHeader(summary);
    buildParams(summary);
    buildExcitation(summary);
    buildChartSections(summary);
    buildSweep(summary);
    buildCoverage(summary);
    setDesign(nominalDesign());
    renderIndices();
    watchResize();
    publishState();
    await predict(null);
  }

  if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', start);
  else start();
})();
