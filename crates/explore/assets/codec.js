/*
 * The compact curves of an answer (`"encoding": "f32"`, docs/explore.md) back into the arrays
 * of numbers the page draws (no DOM: node's test runner imports it). A curve's values are
 * float32, each XORed with its prediction from the two before it (0, then the first value,
 * then 2 v[i-1] - v[i-2] rounded to float32, 0 where that is not finite), the words' bytes in
 * four planes (every word's lowest byte, then every word's second byte, ...), as base64; a
 * band is its half-width the same way (12 significant bits), drawn as the curve minus and plus
 * it.
 */

const word = new DataView(new ArrayBuffer(4));
const bitsOf = (x) => { word.setFloat32(0, x, true); return word.getUint32(0, true); };

/** The prediction of value `i` from the values `v` before it, as float32 bits. */
function predicted(v, i) {
  const p = i === 0 ? 0 : i === 1 ? v[0] : Math.fround(2 * v[i - 1] - v[i - 2]);
  return Number.isFinite(p) ? bitsOf(p) : 0;
}

/** The numbers of a compact curve (base64 planes of float32 words XORed with predictions). */
export function fromF32Base64(text) {
  const bin = atob(text || '');
  const n = bin.length >> 2;
  const out = new Array(n);
  for (let i = 0; i < n; i++) {
    const x = (bin.charCodeAt(i) | (bin.charCodeAt(n + i) << 8) | (bin.charCodeAt(2 * n + i) << 16)
      | (bin.charCodeAt(3 * n + i) << 24)) >>> 0;
    word.setUint32(0, (x ^ predicted(out, i)) >>> 0, true);
    out[i] = word.getFloat32(0, true);
  }
  return out;
}

/**
 * `answer` with its curves as arrays of numbers and its bands as `{lo, hi}` (an answer in
 * the JSON encoding is returned as it is).
 */
export function decodeAnswer(answer) {
  if (!answer || answer.encoding !== 'f32') return answer;
  const channels = {};
  for (const [name, v] of Object.entries(answer.channels || {})) {
    channels[name] = typeof v === 'string' ? fromF32Base64(v) : v;
  }
  const bands = {};
  for (const [name, b] of Object.entries(answer.bands || {})) {
    const x = channels[name];
    const h = fromF32Base64(b.half);
    if (!x) continue;
    bands[name] = { lo: x.map((v, i) => v - h[i]), hi: x.map((v, i) => v + h[i]) };
  }
  return { ...answer, channels, bands };
}
