// The design explorer's page logic under node's test runner (`node --test`, run by
// tests/explore/page_logic.rs): the state's transitions (crates/explore/assets/state.js) as the
// page drives them, without a browser. Each test states a property of the page: a prediction is
// only ever pinned or compared with its own design, a design change aborts the solve in flight
// and its answer is never shown, a solve after a failed prediction is not drawn beside another
// design's, a model without sampled parameters still makes requests.

import test from 'node:test';
import assert from 'node:assert/strict';
import * as S from '../../../crates/explore/assets/state.js';

const SUMMARY = {
  parameters: [
    { name: 'k', nominal: 1e6, min: 5e5, max: 2e6 },
    { name: 'm', nominal: 40, min: 20, max: 80 },
  ],
};

/** A state with the model loaded and its nominal design set. */
function loaded(summary = SUMMARY) {
  const st = S.createState();
  st.summary = summary;
  S.setDesign(st, S.nominalDesign(summary));
  return st;
}

/** What the server answers for a request body (its design echoed, as /api/predict does). */
const answerTo = (body, extra = {}) => ({ design: { ...body.design }, indices: [], t: [0], channels: {}, ...extra });

test('a prediction answered after the design changed is never drawn nor pinned', () => {
  const st = loaded();
  const first = S.startPredict(st);
  S.setParam(st, 'k', 1.5e6);
  const second = S.startPredict(st);
  assert.equal(first.abort.signal.aborted, true, 'the older request is aborted');
  assert.equal(S.requestPin(st), 'pending', 'no prediction of this design yet: the pin waits');
  assert.equal(st.pinned, null);
  // The older answer arrives anyway (it was already on the wire): ignored.
  const late = S.predictAnswered(st, first, answerTo(first.body));
  assert.deepEqual(late, { drawn: false, pinned: false, solveCleared: false });
  assert.equal(st.prediction, null);
  assert.equal(st.pinned, null, 'the older design\'s prediction was paired with the pin');
  // The current design's answer pins the pair.
  const now = S.predictAnswered(st, second, answerTo(second.body));
  assert.equal(now.pinned, true);
  assert.equal(st.pinned.design.k, 1.5e6);
  assert.deepEqual(st.pinned.design, st.pinned.prediction.design, 'A is its design with its own prediction');
  assert.equal(st.pinPending, null);
});

test('pinning with the current prediction on screen takes that pair at once, and keeps it', () => {
  const st = loaded();
  const t = S.startPredict(st);
  S.predictAnswered(st, t, answerTo(t.body));
  assert.equal(S.requestPin(st), 'pinned');
  const pinned = st.pinned;
  S.setParam(st, 'm', 60);
  const t2 = S.startPredict(st);
  S.predictAnswered(st, t2, answerTo(t2.body));
  assert.equal(st.pinned, pinned, 'a later design leaves A alone');
  assert.equal(st.pinned.design.m, 40);
  assert.equal(st.pinned.prediction.design.m, 40);
  assert.equal(S.publicView(st).pinned.design.m, 40);
});

test('a waiting pin is dropped when the design changes again or its prediction fails', () => {
  const st = loaded();
  S.startPredict(st);
  S.setParam(st, 'k', 6e5);
  const t = S.startPredict(st);
  assert.equal(S.requestPin(st), 'pending');
  S.setParam(st, 'k', 7e5);
  assert.equal(st.pinPending, null, 'a pin of a design no longer on screen');
  const t2 = S.startPredict(st);
  S.predictAnswered(st, t, answerTo(t.body));
  assert.equal(st.pinned, null);
  assert.equal(S.requestPin(st), 'pending');
  assert.deepEqual(S.predictFailed(st, t2, 'server fault'), { shown: true, pinDropped: true });
  assert.equal(st.pinned, null);
  assert.equal(st.pinNote, 'dropped');
  assert.equal(S.requestPin(st), 'unavailable', 'no prediction of this design: nothing to pin');
  assert.equal(st.pinned, null);
});

test('a changed design aborts the solve in flight and its answer is never shown', () => {
  const st = loaded();
  const p = S.startPredict(st);
  S.predictAnswered(st, p, answerTo(p.body));
  const solve = S.startSolve(st);
  assert.equal(solve.abort.signal.aborted, false);
  const { solveCancelled } = S.setParam(st, 'k', 1.2e6);
  assert.equal(solveCancelled, true);
  assert.equal(solve.abort.signal.aborted, true, 'the fetch is aborted, which cancels the solve on the server');
  assert.equal(st.solving, null);
  assert.equal(S.solveAnswered(st, solve, answerTo(solve.body)), 'stale');
  assert.equal(st.solve, null);
  assert.equal(S.solveFailed(st, solve), false, 'an aborted solve says nothing more');
  const p2 = S.startPredict(st);
  S.predictAnswered(st, p2, answerTo(p2.body));
  assert.equal(S.solveOverlay(st), null, 'the old design\'s solve drawn over the new design');
  // An excitation change cancels too.
  const again = S.startSolve(st);
  assert.equal(S.setExcitation(st, { kind: 'seed', seed: 1, id: 2 }).solveCancelled, true);
  assert.equal(again.abort.signal.aborted, true);
});

test('a solve of the current design is drawn beside its own prediction only', () => {
  const st = loaded();
  const p = S.startPredict(st);
  const solve = S.startSolve(st);
  assert.equal(S.solveAnswered(st, solve, answerTo(solve.body, { solve_ms: 3 })), 'awaiting prediction');
  assert.equal(S.solveOverlay(st), null);
  S.predictAnswered(st, p, answerTo(p.body));
  assert.equal(S.solveStanding(st, solve.rev), 'shown');
  assert.equal(S.solveOverlay(st).solve_ms, 3);
  // A new design's prediction drops it.
  S.setParam(st, 'm', 30);
  assert.equal(S.solveOverlay(st).solve_ms, 3, 'until the new prediction arrives, the pair on screen stays');
  const p2 = S.startPredict(st);
  assert.equal(S.predictAnswered(st, p2, answerTo(p2.body)).solveCleared, true);
  assert.equal(S.solveOverlay(st), null);
  assert.equal(S.publicView(st).solve, null);
});

test('a solve after a failed prediction is not paired with the older prediction', () => {
  const st = loaded();
  const p = S.startPredict(st);
  S.predictAnswered(st, p, answerTo(p.body));
  S.setParam(st, 'k', 1.9e6);
  const failed = S.startPredict(st);
  S.predictFailed(st, failed, 'server fault (HTTP 500)');
  assert.equal(st.predictError.message, 'server fault (HTTP 500)');
  const solve = S.startSolve(st);
  assert.equal(S.solveAnswered(st, solve, answerTo(solve.body)), 'no prediction', 'the page must say why nothing is drawn');
  assert.equal(S.solveOverlay(st), null, 'the solver\'s curves of one design over another\'s prediction');
  assert.equal(S.currentPrediction(st), null);
  // Predicting the same design again (the level changed) draws the solve beside it.
  const retry = S.startPredict(st);
  S.predictAnswered(st, retry, answerTo(retry.body));
  assert.equal(S.solveOverlay(st).design.k, 1.9e6);
});

test('a superseded prediction\'s failure is not shown', () => {
  const st = loaded();
  const first = S.startPredict(st);
  S.startPredict(st);
  assert.deepEqual(S.predictFailed(st, first, 'aborted'), { shown: false, pinDropped: false });
  assert.equal(st.predictError, null);
});

test('a model without sampled parameters still makes requests', () => {
  const st = loaded({ parameters: [] });
  assert.deepEqual(st.design, {});
  st.excitation = { kind: 'test', sample_id: 900 };
  const t = S.startPredict(st);
  assert.deepEqual(t.body, { design: {}, excitation: { kind: 'test', sample_id: 900 }, encoding: 'f32' });
  S.predictAnswered(st, t, answerTo(t.body));
  assert.equal(S.requestPin(st), 'pinned');
  assert.deepEqual(S.startSolve(st).body.design, {});
});

test('a request asks for the bands of the plotted channels only, at the chosen level', () => {
  const st = loaded();
  st.groups = [
    { key: 'displacement', channels: [{ name: 'z_c' }, { name: 'z_b' }], selected: new Set(['z_c']) },
    { key: 'excitation', channels: [{ name: 'eta' }], selected: new Set(['eta']) },
  ];
  assert.equal(S.requestBody(st).bands, undefined, 'no calibration: no bands asked');
  st.coverage = 0.9;
  const body = S.requestBody(st);
  assert.equal(body.coverage, 0.9);
  assert.deepEqual(body.bands, ['z_c']);
  assert.notEqual(body.design, st.design, 'a copy: later changes do not reach a request sent');
});

test('a dragged slider has one prediction in flight and the latest position is predicted next', () => {
  const st = loaded();
  assert.equal(S.dragWantsPrediction(st), true, 'nothing in flight: predict at once');
  const first = S.startPredict(st);
  assert.equal(first.body.encoding, 'f32', 'predictions ask for the compact curves');
  S.setParam(st, 'k', 1.1e6);
  assert.equal(S.dragWantsPrediction(st), false, 'one in flight: wait for it');
  S.setParam(st, 'k', 1.2e6);
  assert.equal(S.dragWantsPrediction(st), false);
  assert.equal(first.abort.signal.aborted, false, 'a drag never aborts the prediction in flight');
  assert.equal(S.takeDragPending(st), false, 'still in flight: nothing to send yet');
  S.predictAnswered(st, first, answerTo(first.body));
  assert.equal(S.takeDragPending(st), true, 'answered: the latest position goes next');
  assert.equal(S.takeDragPending(st), false, 'once');
  const next = S.startPredict(st);
  assert.equal(next.body.design.k, 1.2e6, 'the latest position, not the ones passed');
  // Releasing the slider predicts the final position: a waiting drag position is dropped.
  S.setParam(st, 'k', 1.3e6);
  assert.equal(S.dragWantsPrediction(st), false);
  const released = S.startPredict(st);
  assert.equal(next.abort.signal.aborted, true);
  S.predictAnswered(st, released, answerTo(released.body));
  assert.equal(S.takeDragPending(st), false);
});
