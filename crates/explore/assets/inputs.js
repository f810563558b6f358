/*
 * The explorer's inputs, built from the model summary: the header (system, model), the level
 * selector of the intervals, one row per design parameter (slider over the training range and
 * a number field, flagged outside it; a model without sampled parameters says so), and the
 * excitation chooser (a test sample, which also sets its design and offers to undo that, or a
 * profile generated from a seed). Every change goes to the state (state.js) and then to
 * `act.changed(result)` and `act.predict(t0)` (main.js).
 */
import { $, el } from './dom.js';
import { fmt, fmtBound, percent, isOutside, roundForDisplay, sliderStep, fieldValue } from './format.js';
import * as S from './state.js';
import { showError, markStale, paramRow, publishState } from './ui.js';

export function renderHeader(summary) {
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

/**
 * The level selector: the calibration's reported levels, unsupported ones disabled;
 * `onChange()` after the state took a new level.
 */
export function buildCoverage(st, onChange) {
  const summary = st.summary;
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
    const v = Number(select.value);
    if (!Number.isFinite(v)) return;
    st.coverage = v;
    publishState(st);
    onChange();
  });
}

/** One row per parameter; a model without sampled parameters gets a note instead. */
export function buildParams(st, act) {
  const summary = st.summary;
  const host = $('#params');
  host.textContent = '';
  if (!summary.parameters.length) {
    host.append(el('p', { class: 'hint params-note', role: 'status' },
      'This model has no sampled parameters: its design is fixed (the description\'s own values). '
      + 'The responses, "Solve exactly", the downloads and the excitation still work; '
      + 'the sweep and the studies need a parameter.'));
    return;
  }
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
        `${fmtBound(p.min, 'min')} … ${fmtBound(p.max, 'max')}`,
        el('span', { class: 'nominal' }, ` · nominal ${fmt(p.nominal)}`)));

    const set = (v, t0) => {
      offerUndo(st, null);
      number.title = '';
      act.changed(S.setParam(st, p.name, v));
      act.predict(t0);
    };
    // Dragging predicts as it goes (one prediction in flight, the latest position next:
    // act.drag); releasing (change) predicts the final position.
    slider.addEventListener('input', () => {
      const v = roundForDisplay(Number(slider.value));
      number.value = String(v);
      markOutside(p, v);
      offerUndo(st, null);
      number.title = '';
      act.drag(p.name, v);
    });
    slider.addEventListener('change', () => {
      const t0 = performance.now();
      const v = roundForDisplay(Number(slider.value));
      number.value = String(v);
      set(v, t0);
    });
    number.addEventListener('change', () => {
      const t0 = performance.now();
      const v = number.valueAsNumber;
      if (!Number.isFinite(v)) {
        showError({ message: `parameter \`${p.name}\` must be a finite number`,
          field: `design.${p.name}`, allowed: 'a finite number' }, 'Input');
        markStale(st, true);
        return;
      }
      slider.value = String(Math.min(p.max, Math.max(p.min, v)));
      set(v, t0);
    });
    host.append(row);
  });
}

function setOutsideFlag(row, out) {
  row.classList.toggle('outside', out);
  $('input[type=number]', row).classList.toggle('outside', out);
  $('.outside-flag', row).hidden = !out;
}

function markOutside(p, v) {
  const row = paramRow(p.name);
  if (row) setOutsideFlag(row, isOutside(p, v));
}

/**
 * Writes the state's design into the panel (sliders, numbers, flags). A number field shows its
 * value rounded to the slider's step when that differs, with the exact value as its tooltip.
 */
export function showDesign(st) {
  for (const p of st.summary.parameters) {
    const v = st.design[p.name];
    const row = paramRow(p.name);
    $('input[type=range]', row).value = String(Math.min(p.max, Math.max(p.min, v)));
    const number = $('input[type=number]', row);
    const shown = fieldValue(p, v);
    number.value = String(shown);
    number.title = shown === v ? '' : `exactly ${v}`;
    markOutside(p, v);
  }
}

/** Sets the whole design (state and panel); returns designChanged's result. */
export function putDesign(st, design) {
  const result = S.setDesign(st, design);
  showDesign(st);
  return result;
}

/** The banner and the per-row flags from a predict answer's `outside`. */
export function renderOutside(st, outside) {
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
  for (const p of st.summary.parameters) setOutsideFlag(paramRow(p.name), names.includes(p.name));
}

/** The excitation chooser (hidden for a system without generated profiles). */
export function buildExcitation(st, act) {
  const ex = st.summary.excitation || {};
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
  st.excitation = readExcitation(st);

  select.addEventListener('change', () => {
    const t0 = performance.now();
    const excitation = readExcitation(st);
    if (!excitation) return;
    act.changed(S.setExcitation(st, excitation));
    const sample = selectedTestSample(st);
    if (sample) {
      const previous = { ...st.design };
      act.changed(putDesign(st, { ...S.nominalDesign(st.summary), ...(sample.design || {}) }));
      offerUndo(st, previous, `Undo: back to the design before test sample ${sample.sample_id}`);
    }
    act.predict(t0);
  });
  for (const id of ['#excitation-seed', '#excitation-id']) {
    $(id).addEventListener('change', () => {
      const t0 = performance.now();
      const excitation = readExcitation(st);
      if (!excitation) return;
      act.changed(S.setExcitation(st, excitation));
      act.predict(t0);
    });
  }
}

/**
 * Offers to put `previous` back (the design a test sample's replaced), or withdraws the
 * offer (`previous` null: the user has changed the design since).
 */
export function offerUndo(st, previous, text) {
  const button = $('#undo-design');
  st.undoDesign = previous;
  button.hidden = !previous;
  if (previous) button.textContent = text;
}

function selectedTestSample(st) {
  const v = $('#excitation').value;
  if (!v.startsWith('test:')) return null;
  const id = Number(v.slice(5));
  return (st.summary.excitation.test_samples || []).find((s) => s.sample_id === id) || null;
}

/**
 * The chooser's excitation; null when invalid: the error shown and the results on screen
 * marked as another excitation's until one is answered again.
 */
function readExcitation(st) {
  const v = $('#excitation').value;
  const seedFields = $('#seed-fields');
  if (v.startsWith('test:')) {
    seedFields.hidden = true;
    return { kind: 'test', sample_id: Number(v.slice(5)) };
  }
  seedFields.hidden = false;
  const seed = $('#excitation-seed').valueAsNumber;
  const id = $('#excitation-id').valueAsNumber;
  for (const [name, x] of [['seed', seed], ['id', id]]) {
    if (!Number.isInteger(x) || x < 0) {
      showError({ message: `excitation ${name} = ${Number.isNaN(x) ? 'nothing' : x} must be a non-negative integer`,
        field: `excitation.${name}`, allowed: 'a non-negative integer' }, 'Input');
      markStale(st, true);
      return null;
    }
  }
  return { kind: 'seed', seed, id };
}
