/*
 * The design explorer's state, in one place, and its transitions (no DOM: node's test runner
 * imports it, tests/browser/unit/state.test.mjs). Every design or excitation change makes a new
 * design revision (`rev`); every request is tagged with the revision, and a copy of the design,
 * it answers, so an answer is only ever drawn, pinned or compared with its own design:
 *   - a prediction supersedes (aborts) the one in flight, and only the latest is drawn;
 *   - "Pin as A" pins the current design with its own prediction, or waits for that
 *     prediction while it is in flight: never an older design's;
 *   - a design change aborts the solve in flight (the server cancels a solve whose client goes
 *     away), and a solve's answer is kept only for the revision it was asked for;
 *   - a solve of a design whose prediction failed says so (see `solveAnswered`).
 * `publicView` is what the page exposes as `window.explorerState`.
 */

/** A fresh state: nothing loaded, nothing in flight. */
export function createState() {
  return {
    summary: null,         // GET /api/model
    design: {},            // {NAME: number}, what the next request sends
    excitation: null,      // the request's excitation, or null (a system without profiles)
    coverage: null,        // the intervals' level sent with every request (null: no calibration)
    rev: 0,                // the design revision: bumped on every design or excitation change
    stale: false,          // an input was refused: the results shown are an older design's
    undoDesign: null,      // the design a test sample replaced, while its undo is offered
    predictSeq: 0,         // sequence number of the latest prediction request
    predicting: null,      // the prediction in flight: {seq, rev, body, abort}
    dragPending: false,    // a dragged slider moved on while its prediction was in flight
    prediction: null,      // the last prediction drawn: {rev, design, excitation, answer}
    predictError: null,    // why the latest prediction failed: {rev, message}
    solving: null,         // the solve in flight: {rev, body, abort}
    solve: null,           // the last solve answered: {rev, answer}
    pinned: null,          // design A: {rev, design, excitation, prediction}
    pinPending: null,      // the revision to pin once its prediction arrives
    pinNote: null,         // why the last "Pin as A" pinned nothing: 'unavailable' | 'dropped'
    sweep: null,           // the last sweep answer
    sweepRequest: null,    // its request
    groups: [],            // the chart sections: [{key, channels, selected: Set, ...}]
    busy: { predicting: 0, solving: 0, sweeping: 0 },
    counters: { predictions: 0, solves: 0, sweeps: 0, solvesCancelled: 0 },
  };
}

/** The model's nominal design. */
export function nominalDesign(summary) {
  const d = {};
  for (const p of summary.parameters) d[p.name] = p.nominal;
  return d;
}

/**
 * A design or excitation changed: a new revision. The solve in flight (another revision's) is
 * aborted and a pin waiting for another revision's prediction dropped. Returns
 * `{solveCancelled}`.
 */
export function designChanged(st) {
  st.rev += 1;
  let solveCancelled = false;
  if (st.solving && st.solving.rev !== st.rev) {
    st.solving.abort.abort();
    st.solving = null;
    solveCancelled = true;
  }
  if (st.pinPending != null && st.pinPending !== st.rev) st.pinPending = null;
  st.pinNote = null;
  return { solveCancelled };
}

/** Sets one parameter (see `designChanged`). */
export function setParam(st, name, v) {
  st.design[name] = v;
  return designChanged(st);
}

/** Sets every parameter of the model: `design`'s values, the nominal for the rest. */
export function setDesign(st, design) {
  for (const p of st.summary.parameters) st.design[p.name] = design[p.name] != null ? design[p.name] : p.nominal;
  return designChanged(st);
}

/** Sets the excitation (see `designChanged`). */
export function setExcitation(st, excitation) {
  st.excitation = excitation;
  return designChanged(st);
}

/** The channels whose bands a request asks for: the plotted ones (excitations have none). */
export function bandChannels(st) {
  return st.groups.filter((g) => g.key !== 'excitation')
    .flatMap((g) => g.channels.filter((c) => g.selected.has(c.name)).map((c) => c.name));
}

/** The body of predict / solve / download requests for the current design. */
export function requestBody(st) {
  const body = { design: { ...st.design } };
  if (st.excitation) body.excitation = { ...st.excitation };
  if (st.coverage != null) {
    body.coverage = st.coverage;
    body.bands = bandChannels(st);
  }
  return body;
}

/**
 * A prediction of the current design goes out: the one in flight is aborted (superseded), and
 * so is a drag position waiting for it. It asks for the compact curves (`encoding: f32`).
 * Returns its ticket `{seq, rev, body, abort}` (`abort`: the fetch's AbortController).
 */
export function startPredict(st) {
  if (st.predicting) st.predicting.abort.abort();
  st.dragPending = false;
  const ticket = {
    seq: ++st.predictSeq, rev: st.rev, body: { ...requestBody(st), encoding: 'f32' }, abort: new AbortController(),
  };
  st.predicting = ticket;
  return ticket;
}

/**
 * A dragged slider's new position wants a prediction: `true` to send it now (none in flight),
 * else `false` and it is sent once the one in flight ends (`takeDragPending`), so a drag has
 * at most one prediction in flight and the latest position is always predicted next.
 */
export function dragWantsPrediction(st) {
  if (st.predicting) {
    st.dragPending = true;
    return false;
  }
  return true;
}

/** After a prediction ended: whether a drag position waits for its prediction (now taken). */
export function takeDragPending(st) {
  const pending = st.dragPending && !st.predicting;
  if (pending) st.dragPending = false;
  return pending;
}

/** Whether `ticket` is the latest prediction request (an older one is never drawn). */
export const isLatestPrediction = (st, ticket) => ticket.seq === st.predictSeq;

/**
 * The answer of prediction `ticket`. The latest becomes the prediction drawn, tagged with its
 * design; a solve of another revision is dropped; a pin waiting for it pins it. Returns
 * `{drawn, pinned, solveCleared}` (`drawn` false: superseded, ignore it).
 */
export function predictAnswered(st, ticket, answer) {
  if (!isLatestPrediction(st, ticket)) return { drawn: false, pinned: false, solveCleared: false };
  st.predicting = null;
  st.predictError = null;
  st.prediction = {
    rev: ticket.rev, design: ticket.body.design, excitation: ticket.body.excitation || null, answer,
  };
  let solveCleared = false;
  if (st.solve && st.solve.rev !== ticket.rev) {
    st.solve = null;
    solveCleared = true;
  }
  let pinned = false;
  if (st.pinPending === ticket.rev) {
    pinPrediction(st);
    pinned = true;
  }
  return { drawn: true, pinned, solveCleared };
}

/**
 * Prediction `ticket` failed with `message`. Returns `{shown, pinDropped}` (`shown` false: it
 * was superseded or aborted, say nothing; `pinDropped`: a pin was waiting for it).
 */
export function predictFailed(st, ticket, message) {
  if (!isLatestPrediction(st, ticket)) return { shown: false, pinDropped: false };
  st.predicting = null;
  st.predictError = { rev: ticket.rev, message };
  const pinDropped = st.pinPending === ticket.rev;
  if (pinDropped) {
    st.pinPending = null;
    st.pinNote = 'dropped';
  }
  return { shown: true, pinDropped };
}

/** The prediction drawn if it is the current design's, else null. */
export function currentPrediction(st) {
  return st.prediction && st.prediction.rev === st.rev ? st.prediction : null;
}

function pinPrediction(st) {
  const p = st.prediction;
  st.pinned = {
    rev: p.rev, design: { ...p.design }, excitation: p.excitation ? { ...p.excitation } : null, prediction: p.answer,
  };
  st.pinPending = null;
  st.pinNote = null;
}

/**
 * "Pin as A": `pinned` (the current design with its own prediction), `pending` (its prediction
 * is in flight: pinned when it arrives) or `unavailable` (the current design has no prediction:
 * it failed or was refused).
 */
export function requestPin(st) {
  if (currentPrediction(st)) {
    pinPrediction(st);
    return 'pinned';
  }
  if (st.predicting && st.predicting.rev === st.rev) {
    st.pinPending = st.rev;
    return 'pending';
  }
  st.pinNote = 'unavailable';
  return 'unavailable';
}

/** "Unpin A" (a waiting pin included). */
export function unpin(st) {
  st.pinned = null;
  st.pinPending = null;
  st.pinNote = null;
}

/** A solve of the current design goes out (aborting any other). Returns its ticket. */
export function startSolve(st) {
  if (st.solving) st.solving.abort.abort();
  const ticket = { rev: st.rev, body: requestBody(st), abort: new AbortController() };
  st.solving = ticket;
  return ticket;
}

/**
 * The answer of solve `ticket`: `stale` (the design changed since: never shown), else it is
 * kept for its revision and this says whether it can be drawn: `shown` (beside the current
 * design's prediction), `awaiting prediction` (that prediction is in flight) or
 * `no prediction` (it failed: `st.predictError` says why).
 */
export function solveAnswered(st, ticket, answer) {
  if (st.solving !== ticket || ticket.rev !== st.rev) {
    if (st.solving === ticket) st.solving = null;
    return 'stale';
  }
  st.solving = null;
  st.solve = { rev: ticket.rev, answer };
  return solveStanding(st, ticket.rev);
}

/**
 * Where the solve answered for revision `rev` stands: `stale` (the design changed since),
 * `shown`, `awaiting prediction` or `no prediction` (see `solveAnswered`).
 */
export function solveStanding(st, rev) {
  if (rev !== st.rev || !st.solve || st.solve.rev !== rev) return 'stale';
  if (st.prediction && st.prediction.rev === rev) return 'shown';
  if (st.predicting && st.predicting.rev === rev) return 'awaiting prediction';
  return 'no prediction';
}

/** Solve `ticket` failed: whether to say so (false: aborted by a design change or superseded). */
export function solveFailed(st, ticket) {
  if (st.solving !== ticket) return false;
  st.solving = null;
  return true;
}

/** The solve answer to draw: only beside the prediction of the same revision. */
export function solveOverlay(st) {
  const s = st.solve;
  const p = st.prediction;
  return s && p && s.rev === p.rev ? s.answer : null;
}

/** What the page exposes as `window.explorerState` (the API answers and the design). */
export function publicView(st) {
  return {
    summary: st.summary,
    design: { ...st.design },
    excitation: st.excitation ? { ...st.excitation } : null,
    prediction: st.prediction ? st.prediction.answer : null,
    solve: st.solve ? st.solve.answer : null,
    sweep: st.sweep,
    coverage: st.coverage,
    stale: !!st.stale,
    rev: st.rev,
    pinned: st.pinned ? {
      design: { ...st.pinned.design }, excitation: st.pinned.excitation, prediction: st.pinned.prediction,
    } : null,
  };
}
