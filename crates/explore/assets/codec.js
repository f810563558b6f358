/*
 * The compact curves of an answer (`"encoding": "f32"`, docs/explore.md) back into the arrays
 * of numbers the page draws (no DOM: node's test runner imports it). Each curve is the base64
 * text of its values as float32, each XORed with the one before it, in four byte planes (every
 * word's lowest byte, then every word's second byte, ...); each band is its half-width the same
 * way, drawn as the curve minus and plus it.
 */

/** The numbers of a compact curve (base64 float32 planes of successive XORs), as an Array. */
export function fromF32Base64(text) {
  const bin = atob(text || '');
  const n = bin.length >> 2;
  const word = new DataView(new ArrayBuffer(4));
  const out = new Array(n);
  let previous = 0;
  for (let i = 0; i < n; i++) {
    const x = (bin.charCodeAt(i) | (bin.charCodeAt(n + i) << 8) | (bin.charCodeAt(2 * n + i) << 16)
      | (bin.charCodeAt(3 * n + i) << 24)) >>> 0;
    previous = (previous ^ x) >>> 0;
    word.setUint32(0, previous, true);
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
