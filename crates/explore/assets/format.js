/*
 * Numbers and names as the explorer's pages show them (no DOM: node's test runner imports it,
 * tests/browser/unit): `fmt` (4 significant digits, exponent form when very large or small),
 * signed values and percentages, a level as a percentage, a name with its unit, a limit, a
 * colour at an opacity, and how a parameter's number field shows a value (rounded to its
 * slider's step).
 */

/** A number for people: 4 significant digits, exponent form when very large or small. */
export function fmt(v, digits = 4) {
  if (v == null) return '—';
  if (typeof v !== 'number') return String(v);
  if (!Number.isFinite(v)) return String(v);
  const a = Math.abs(v);
  if (a !== 0 && (a >= 1e5 || a < 1e-3)) {
    const [m, e] = v.toExponential(digits - 1).split('e');
    return `${m.includes('.') ? m.replace(/\.?0+$/, '') : m}e${e.replace('+', '')}`;
  }
  return String(Number(v.toPrecision(digits)));
}

/**
 * A bound of a training range as its label shows it: the fewest significant digits (4 to 8)
 * that give the value exactly, else 6 digits rounded inwards (`side` `min` up, `max` down),
 * so a label never shows a value outside the range it names.
 */
export function fmtBound(v, side) {
  if (v == null || !Number.isFinite(v)) return fmt(v);
  for (let d = 4; d <= 8; d++) {
    if (Number(v.toPrecision(d)) === v) return fmt(v, d);
  }
  const shown = Number(v.toPrecision(6));
  if (side === 'min' ? shown >= v : shown <= v) return fmt(shown, 6);
  const e = Math.floor(Math.log10(Math.abs(v))) - 5;
  const step = 10 ** e;
  const inward = (side === 'min' ? Math.ceil(v / step) : Math.floor(v / step)) * step;
  return fmt(Number(inward.toPrecision(6)), 6);
}

/** `fmt` with a `+` before a positive value. */
export function fmtSigned(v, digits = 4) {
  if (v == null || !Number.isFinite(v)) return fmt(v, digits);
  return (v > 0 ? '+' : '') + fmt(v, digits);
}

/** A fraction as a percentage (`0.0123` -> `1.23 %`), `—` when unknown. */
export function fmtPercent(fraction, signed = false) {
  if (fraction == null || !Number.isFinite(fraction)) return '—';
  const p = fraction * 100;
  const a = Math.abs(p);
  const s = a >= 100 ? p.toFixed(0) : a >= 10 ? p.toFixed(1) : p.toFixed(2);
  return `${signed && p > 0 ? '+' : ''}${s} %`;
}

/** A coverage level as a percentage: `0.9` -> `90 %`. */
export const percent = (level) => `${Number((level * 100).toPrecision(4))} %`;

/** `name [unit]`, or the name alone without a unit. */
export const withUnit = (name, unit) => (unit ? `${name} [${unit}]` : name);

/** An index's limit: `≤ 170`, `≥ 0.2`, `—` without one. */
export function limitText(limit) {
  if (!limit) return '—';
  return `${limit.kind === 'min' ? '≥' : '≤'} ${fmt(limit.value)}`;
}

/** `#rrggbb` at opacity `alpha` as a CSS colour. */
export function withAlpha(hex, alpha) {
  const n = parseInt(hex.slice(1), 16);
  return `rgba(${(n >> 16) & 255}, ${(n >> 8) & 255}, ${n & 255}, ${alpha})`;
}

/** Whether `v` lies outside parameter `p`'s training range. */
export const isOutside = (p, v) => v < p.min || v > p.max;

/** Rounds a slider-derived value so the number field shows what is sent. */
export const roundForDisplay = (v) => Number(v.toPrecision(6));

/** The slider step of parameter `p`: a thousandth of its training range. */
export const sliderStep = (p) => (p.max - p.min) / 1000;

/**
 * `v` as parameter `p`'s number field shows it when the design comes from elsewhere (a test
 * sample): rounded to the decimals of the slider's step, so the field does not overflow.
 */
export function fieldValue(p, v) {
  const step = sliderStep(p);
  if (!(step > 0) || !Number.isFinite(v)) return roundForDisplay(v);
  const decimals = Math.min(12, Math.max(0, Math.ceil(-Math.log10(step))));
  return Number(v.toFixed(decimals));
}
