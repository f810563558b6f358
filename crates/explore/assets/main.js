/*
 * pino-mbd design explorer — the browser side of `explore` (served as /assets/main.js, an ES
 * module; the page's other modules are imported from here).
 *
 * What it does:
 *   - reads the model summary (GET /api/model) and builds everything from it (inputs.js: one
 *     row per design parameter, the excitation chooser, the level selector; charts.js: one
 *     chart section per channel group; tables.js: the indices; sweep.js, studies-start.js).
 *     Nothing here is written for one particular system; a model without sampled parameters
 *     says so and still predicts, solves and downloads its one design.
 *   - on every design or excitation change asks the surrogate (POST /api/predict, the compact
 *     float32 curves decoded by codec.js) and redraws, while a slider is dragged too (one
 *     prediction in flight, the latest position next);
 *     "Solve exactly" (POST /api/solve) overlays the exact solver's curves (dashed) and shows
 *     the surrogate's errors; "Pin as A" keeps a design with its own prediction to compare the
 *     following ones with; downloads fetch the design YAML and the curves (CSV / Parquet).
 *   - the state lives in one object (state.js): every request is tagged with the design
 *     revision it answers; a newer prediction aborts the older, a design change aborts the
 *     solve in flight (the server cancels it), a pin waits for its design's prediction, and an
 *     answer is never drawn beside another design's.
 *
 * Hooks for browser tests:
 *   window.explorerState   = state.js's publicView: {summary, design, excitation, prediction,
 *                            solve, sweep, coverage, stale, rev, pinned}
 *   window.explorerMetrics = {predictToRedrawMs: [...]}   (change event -> redraw done, ms;
 *                            the predictions of a slider while it is dragged are not timed)
 *   window.explorerCharts, window.explorerBandAlpha: see charts.js
 *   body[data-state]       = loading | idle | predicting | solving | sweeping
 *   body[data-predictions], body[data-solves], body[data-sweeps]: counters bumped after drawing
 *   body[data-solves-cancelled]: solves aborted by a design change
 *   body[data-pinned]: set while a design is pinned as A
 *   body[data-study], body[data-study-state]: see studies-start.js
 *
 * ES2020 modules, no framework, no build step; the only dependency is the vendored uPlot
 * (global `uPlot`, see VENDORED.md). No inline scripts, no eval (CSP `script-src 'self'`).
 */
import { $, el } from './dom.js';
import { fmt } from './format.js';
import { api, ApiError, postRetryingOnce, isAbort, sleep } from './api.js';
import { decodeAnswer } from './codec.js';
import * as S from './state.js';
import { solvedWithoutPrediction } from './verdicts.js';
import {
  showError, clearError, markStale, setBusy, bumpCounter, nextFrame, publishState,
} from './ui.js';
import {
  renderHeader, buildCoverage, buildParams, buildExcitation, showDesign, putDesign, renderOutside, offerUndo,
} from './inputs.js';
import { renderIndices } from './tables.js';
import { buildChartSections, renderAllCharts, watchResize } from './charts.js';
import { buildSweep, runSweep, sweepChart } from './sweep.js';

const st = S.createState();
window.explorerMetrics = { predictToRedrawMs: [] };
publishState(st);

/** What the inputs call: after a design change, to predict, and while a slider is dragged. */
const act = { changed, predict, drag };

/** A slider dragged to `v`: the design follows, and its prediction goes out when none is in
 * flight (else once the one in flight ends: state.js's dragWantsPrediction). */
function drag(name, v) {
  changed(S.setParam(st, name, v));
  if (S.dragWantsPrediction(st)) predict(null);
}

/** After a design or excitation change (state.js's designChanged result). */
function changed(result) {
  if (result.solveCancelled) {
    $('#solve-status').textContent = 'solve cancelled: the design changed; solve again';
    bumpCounter(st, 'solvesCancelled');
  }
  publishState(st);
  renderPin();
}

/** Redraws everything that shows the prediction, the solve and the pin. */
function renderResults() {
  renderIndices(st);
  renderAllCharts(st);
  renderPin();
}

// -----------------------------------------------------------------------------------------
// Predict
// -----------------------------------------------------------------------------------------

/**
 * Asks the surrogate for the current design and redraws. `t0` (performance.now() of the
 * user's change event) is recorded in explorerMetrics once the redraw is done. A newer
 * request supersedes (aborts) an older one still in flight.
 */
async function predict(t0 = null) {
  const ticket = S.startPredict(st);
  setBusy(st, 'predicting', +1);
  $('#predict-status').textContent = 'predicting…';
  renderPin();
  try {
    const answer = decodeAnswer(await api('POST', '/api/predict', ticket.body, { signal: ticket.abort.signal }));
    if (!S.isLatestPrediction(st, ticket)) return;
    await nextFrame();
    const { drawn, solveCleared } = S.predictAnswered(st, ticket, answer);
    if (!drawn) return;
    if (solveCleared) $('#solve-status').textContent = '';
    clearError();
    markStale(st, false);
    renderOutside(st, answer.outside);
    renderResults();
    $('#predict-status').textContent = answer.elapsed_ms != null
      ? `surrogate: ${fmt(answer.elapsed_ms, 3)} ms` : '';
    // uPlot commits its redraw in a microtask queued by setData; measure after it.
    await Promise.resolve();
    if (t0 != null) window.explorerMetrics.predictToRedrawMs.push(performance.now() - t0);
    bumpCounter(st, 'predictions');
  } catch (err) {
    const { shown } = S.predictFailed(st, ticket, (err && err.message) || String(err));
    if (shown && !isAbort(err)) {
      $('#predict-status').textContent = '';
      showError(err, 'Prediction');
      // A refused input leaves the last answer on screen, marked as another design's.
      if (err instanceof ApiError && err.status === 400) markStale(st, true);
    }
  } finally {
    publishState(st);
    setBusy(st, 'predicting', -1);
    renderPin();
    if (S.takeDragPending(st)) predict(null);
  }
}

// -----------------------------------------------------------------------------------------
// Solve exactly
// -----------------------------------------------------------------------------------------

async function solve() {
  const button = $('#solve');
  const status = $('#solve-status');
  const ticket = S.startSolve(st);
  button.disabled = true;
  button.classList.add('busy');
  status.textContent = 'solving…';
  setBusy(st, 'solving', +1);
  try {
    const answer = await postRetryingOnce('/api/solve', ticket.body, {
      signal: ticket.abort.signal,
      onWait: (left) => { status.textContent = left ? `solver busy, retrying in ${left} s` : 'retrying…'; },
    });
    let outcome = S.solveAnswered(st, ticket, answer);
    if (outcome === 'stale') return;
    // The prediction of this design may still be on its way: wait for it.
    while (outcome === 'awaiting prediction') {
      await sleep(20);
      outcome = S.solveStanding(st, ticket.rev);
    }
    if (outcome === 'stale') return;
    await nextFrame();
    publishState(st);
    if (outcome === 'no prediction') {
      status.textContent = solvedWithoutPrediction(answer, st.predictError && st.predictError.message);
    } else {
      clearError();
      renderResults();
      status.textContent = answer.solve_ms != null ? `solver: ${fmt(answer.solve_ms, 3)} ms` : 'solved';
    }
    await Promise.resolve();
    bumpCounter(st, 'solves');
  } catch (err) {
    if (S.solveFailed(st, ticket) && !isAbort(err)) {
      status.textContent = '';
      showError(err, 'Solve');
    }
  } finally {
    button.disabled = false;
    button.classList.remove('busy');
    setBusy(st, 'solving', -1);
  }
}

// -----------------------------------------------------------------------------------------
// Pin A / compare B
// -----------------------------------------------------------------------------------------

function pin() {
  S.requestPin(st);
  publishState(st);
  renderResults();
}

function unpin() {
  S.unpin(st);
  publishState(st);
  renderResults();
}

/** The pin buttons, body[data-pinned] and the pin info: what A is and how B differs from it. */
function renderPin() {
  const a = st.pinned;
  $('#pin').disabled = !st.prediction && !st.predicting;
  $('#unpin').disabled = !a && st.pinPending == null;
  if (a) document.body.dataset.pinned = 'true'; else delete document.body.dataset.pinned;
  const info = $('#pin-info');
  if (st.pinNote) {
    info.textContent = st.pinNote === 'dropped'
      ? 'Not pinned: the prediction of this design failed.'
      : 'Not pinned: this design has no prediction (it failed); change it or predict again.';
    return;
  }
  if (st.pinPending != null) {
    info.textContent = 'Pinning this design as A once its prediction arrives…';
    return;
  }
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

// -----------------------------------------------------------------------------------------
// Downloads and start
// -----------------------------------------------------------------------------------------

async function download(button, path, filename) {
  button.disabled = true;
  try {
    const blob = await api('POST', path, S.requestBody(st), { as: 'blob' });
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

function undoDesign() {
  const previous = st.undoDesign;
  if (!previous) return;
  const t0 = performance.now();
  changed(putDesign(st, previous));
  offerUndo(st, null);
  predict(t0);
}

function wireButtons() {
  $('#error-dismiss').addEventListener('click', clearError);
  $('#reset').addEventListener('click', () => {
    const t0 = performance.now();
    offerUndo(st, null);
    changed(putDesign(st, S.nominalDesign(st.summary)));
    predict(t0);
  });
  $('#solve').addEventListener('click', solve);
  $('#undo-design').addEventListener('click', undoDesign);
  $('#pin').addEventListener('click', pin);
  $('#unpin').addEventListener('click', unpin);
  for (const [id, path, file] of [
    ['#download-design', '/api/download/design', 'design.yaml'],
    ['#download-csv', '/api/download/curves?format=csv', 'curves.csv'],
    ['#download-parquet', '/api/download/curves?format=parquet', 'curves.parquet'],
  ]) {
    $(id).addEventListener('click', (e) => download(e.currentTarget, path, file));
  }
}

/** A newly plotted channel's band comes with the next prediction. */
function onPick(group, channel, checked) {
  const pred = st.prediction && st.prediction.answer;
  if (checked && st.coverage != null && group.key !== 'excitation' && pred
    && !(pred.bands && pred.bands[channel.name])) predict();
}

async function start() {
  for (const k of ['predictions', 'solves', 'sweeps']) document.body.dataset[k] = '0';
  wireButtons();
  try {
    st.summary = await api('GET', '/api/model');
  } catch (err) {
    showError(err, 'Loading the model');
    document.body.dataset.state = 'idle';
    return;
  }
  try {
    const summary = st.summary;
    renderHeader(summary);
    buildParams(st, act);
    buildExcitation(st, act);
    buildChartSections(st, onPick);
    buildSweep(st);
    buildCoverage(st, () => {
      predict(performance.now());
      if (st.sweep) runSweep(st);
    });
    S.setDesign(st, S.nominalDesign(summary));
    showDesign(st);
    renderIndices(st);
    renderPin();
    watchResize(st, sweepChart);
    publishState(st);
  } catch (err) {
    // Never stay on "loading" without a word: say what failed and predict what can be.
    showError(err, 'Building the page from the model');
  }
  await predict(null);
}

start();
