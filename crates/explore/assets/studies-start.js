/*
 * A study started from the sweep view (POST /api/studies; shown on /studies): a Monte Carlo or
 * Sobol study of the swept parameter over the sweep's from-to and, optionally, a second
 * parameter over its own interval, the others at the current design; followed until it ends,
 * with a link to its card (body[data-study], body[data-study-state] for the tests).
 */
import { $, el } from './dom.js';
import { withUnit } from './format.js';
import { api, sleep } from './api.js';
import { showError, clearError } from './ui.js';

export function buildStudyStart(st) {
  const summary = st.summary;
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
      const p = summary.parameters.find((q) => q.name === second.value);
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
  $('#start-study').addEventListener('click', () => startStudy(st));
}

async function startStudy(st) {
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

/** Polls the Studies list until the started study `name` is finished, failed or cancelled. */
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
