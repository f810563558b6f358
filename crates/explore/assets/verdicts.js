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
 * null): `{text, pass, source}` (`source`: `solver` or `surrogate`), or null without `pred`.
 */
export function headline(pred, solve) {
  if (!pred) return null;
  const extrapolated = (pred.outside || []).length > 0 || pred.extrapolated;
  if (solve) {
    return {
      text: `solver: ${said(solve)}; surrogate: ${said(pred)}${extrapolated ? ' (extrapolated)' : ''}`,
      pass: !!solve.pass, source: 'solver',
    };
  }
  return { text: `${said(pred)}${extrapolated ? ' (surrogate, extrapolated)' : ''}`, pass: !!pred.pass, source: 'surrogate' };
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

