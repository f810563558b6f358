/*
 * What the explorer says about a design (no DOM: node's test runner imports it): the headline
 * verdict (the solver's once it answered the design, the surrogate's beside it), the
 * three-valued verdict of the calibrated intervals, and which surrogate errors stand out.
 */
import { fmt, percent } from './format.js';

/** A surrogate error (relative, of an index or a channel's L2) above this stands out. */
export const LARGE_ERROR = 0.10;

/** Whether a relative error stands out (above LARGE_ERROR). */
export function isLarge(e) {
  return e != null && Number.isFinite(e) && Math.abs(e) > LARGE_ERROR;
}

/** An answer's limits in words: `all limits met` or `fails a, b`. */
export const said = (answer) => (answer.pass ? 'all limits met' : `fails ${(answer.failed || []).join(', ')}`);

/**
 * The headline verdict of prediction `pred` and the solve `solve` of the same design (or
 * null): `{text, pass, source, tone}` (`source`: `solver` or `surrogate`; `tone`: `pass`,
 * `uncertain` or `fail`, its colour), or null without `pred`. The solver's verdict is the
 * design's; the surrogate's alone is never green where the intervals say to solve the design
 * (`uncertain`) or where the design is extrapolated (no claim), so it never contradicts the
 * intervals' verdict beside it.
 */
export function headline(pred, solve) {
  if (!pred) return null;
  const extrapolated = (pred.outside || []).length > 0 || pred.extrapolated;
  if (solve) {
    return {
      text: `solver: ${said(solve)}; surrogate: ${said(pred)}${extrapolated ? ' (extrapolated)' : ''}`,
      pass: !!solve.pass, source: 'solver', tone: solve.pass ? 'pass' : 'fail',
    };
  }
  const unsure = !!pred.pass && (extrapolated || pred.verdict === 'uncertain');
  let text = said(pred);
  if (extrapolated) text += pred.pass ? ' by the surrogate, extrapolated: no claim, solve it' : ' (surrogate, extrapolated)';
  else if (unsure) text += ' by the surrogate, but its intervals straddle a limit: solve it';
  return { text, pass: !!pred.pass, source: 'surrogate', tone: !pred.pass ? 'fail' : unsure ? 'uncertain' : 'pass' };
}

/**
 * The intervals' verdict of `pred`: `{text, verdict, extrapolated, title}` (`verdict`: pass,
 * uncertain, fail, `''` without a limit or without intervals), or null without `pred`.
 */
export function intervalVerdict(pred, calibrationNote) {
  if (!pred) return null;
  if (pred.coverage == null) {
    return { text: 'no error bar', verdict: '', extrapolated: false, title: pred.no_intervals || calibrationNote || '' };
  }
  const v = pred.verdict;
  const what = { pass: 'pass', uncertain: 'uncertain: send to the solver', fail: 'fail' }[v] || 'no limit';
  return {
    text: `at ${percent(pred.coverage)}: ${what}`, verdict: v || '', extrapolated: !!pred.extrapolated,
    title: 'the calibrated intervals against the limits (docs/uncertainty.md)',
  };
}

/**
 * What "Solve exactly" says once the solver answered a design the surrogate has no prediction
 * of (it failed: `why`): the solver's verdict, and why its curves are not drawn.
 */
export function solvedWithoutPrediction(solve, why) {
  const ms = solve.solve_ms != null ? ` in ${fmt(solve.solve_ms, 3)} ms` : '';
  return `solver${ms}: ${said(solve)}. Not drawn: the surrogate's prediction of this design failed`
    + `${why ? ` (${why})` : ''}, so there is nothing to compare it with; change the design or the level to predict again.`;
}

