/*
 * The explorer page's shared view of its state: the error box (a `design.NAME` field marks its
 * parameter row), the "out of date" mark, body[data-state] from the requests in flight, the
 * counters the browser test waits on (body[data-predictions] ...), `window.explorerState`
 * (state.js's publicView) and the next animation frame.
 */
import { $ } from './dom.js';
import { ApiError, isAbort } from './api.js';
import { publicView } from './state.js';

/** Publishes the state as `window.explorerState`. */
export function publishState(st) {
  window.explorerState = publicView(st);
}

/** The row of parameter `name` in the design panel. */
export function paramRow(name) {
  return [...document.querySelectorAll('#params .param')].find((r) => r.dataset.param === name);
}

/** Shows an error in the #error box; `context` says what was being done. */
export function showError(err, context) {
  if (isAbort(err)) return;
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

export function clearError() {
  const box = $('#error');
  box.hidden = true;
  box.dataset.field = '';
  document.querySelectorAll('.param.invalid').forEach((r) => r.classList.remove('invalid'));
}

/**
 * Marks the results as those of an older design (an input was refused): greyed, with the
 * "out of date" banner, until a prediction of the design on screen arrives.
 */
export function markStale(st, stale) {
  st.stale = stale;
  document.body.classList.toggle('stale', stale);
  $('#stale-banner').hidden = !stale;
  publishState(st);
}

/** One more (`+1`) or one fewer (`-1`) request of `kind` in flight: body[data-state]. */
export function setBusy(st, kind, delta) {
  st.busy[kind] = Math.max(0, st.busy[kind] + delta);
  const b = st.busy;
  document.body.dataset.state = b.solving ? 'solving' : b.sweeping ? 'sweeping'
    : b.predicting ? 'predicting' : 'idle';
}

/** Bumps body[data-NAME] once an answer is drawn. */
export function bumpCounter(st, name) {
  st.counters[name] += 1;
  document.body.dataset[name] = String(st.counters[name]);
}

export const nextFrame = () => new Promise((resolve) => requestAnimationFrame(() => resolve()));
