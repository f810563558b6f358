// The explorer page's pure helpers under node's test runner (run by tests/explore/page_logic.rs):
// number formatting (format.js), the curves' arithmetic (series.js), the verdicts the page
// states (verdicts.js) and the API wrapper (api.js) against a local HTTP server: an aborted
// request closes its connection (which is how the server learns to cancel a solve).

import test from 'node:test';
import assert from 'node:assert/strict';
import http from 'node:http';
import { fmt, fmtBound, fmtPercent, fieldValue, percent, limitText } from '../../../crates/explore/assets/format.js';
import { decodeAnswer, fromF32Base64 } from '../../../crates/explore/assets/codec.js';
import { alignTo, channelColor, runsOf, indexInside, channelInside } from '../../../crates/explore/assets/series.js';
import { headline, intervalVerdict, solvedWithoutPrediction, isLarge } from '../../../crates/explore/assets/verdicts.js';
import { api, ApiError, postRetryingOnce, isAbort } from '../../../crates/explore/assets/api.js';

test('numbers are shown to 4 significant digits, exponents when very large or small', () => {
  assert.equal(fmt(123456), '1.235e5');
  assert.equal(fmt(0.000123), '1.23e-4');
  assert.equal(fmt(12.34567), '12.35');
  assert.equal(fmt(null), '—');
  assert.equal(fmtPercent(0.1234, true), '+12.3 %');
  assert.equal(percent(0.9), '90 %');
  assert.equal(limitText({ kind: 'max', value: 170 }), '≤ 170');
  // A number field shows a value rounded to its slider's step (a thousandth of the range).
  assert.equal(fieldValue({ min: 0, max: 1 }, 0.123456789), 0.123);
});

test('the channels of a group never share a colour', () => {
  const colours = Array.from({ length: 40 }, (_, i) => channelColor(i));
  assert.equal(new Set(colours).size, colours.length);
  assert.ok(colours.every((c) => /^#[0-9a-f]{6}$/.test(c)));
});

test('curves are resampled onto the prediction\'s times; runs of flags found', () => {
  assert.deepEqual(alignTo([0, 1, 2], [0, 2], [0, 4]), [0, 2, 4]);
  assert.deepEqual(alignTo([0, 1, 3], [0, 2], [0, 4]), [0, 2, null]);
  assert.deepEqual(runsOf([false, true, true, false, true]), [[1, 2], [4, 4]]);
  const pred = { coverage: 0.9, indices: [{ name: 'f', lo: 1, hi: 2 }] };
  assert.equal(indexInside(pred, { coverage: 0.9, indices: [{ name: 'f', value: 3 }] }, 'f'), false);
  assert.equal(indexInside(pred, { coverage: 0.8, index_inside: { f: false }, indices: [{ name: 'f', value: 1.5 }] }, 'f'), true);
});

test('the headline follows the solver once it answered, the surrogate beside it', () => {
  const pred = { pass: true, failed: [], outside: [] };
  const solve = { pass: false, failed: ['peak'] };
  assert.deepEqual(headline(pred, solve), { text: 'solver: fails peak; surrogate: all limits met', pass: false, source: 'solver', tone: 'fail' });
  assert.equal(headline(pred, null).source, 'surrogate');
  assert.equal(headline(null, solve), null);
  assert.equal(intervalVerdict({ coverage: 0.9, verdict: 'uncertain' }).text, 'at 90 %: uncertain: send to the solver');
  assert.equal(intervalVerdict({ coverage: null, no_intervals: 'no calibration' }).title, 'no calibration');
  assert.equal(isLarge(-0.2), true);
  assert.equal(isLarge(0.05), false);
});

test('the surrogate\'s headline is never green where the intervals say to solve or it extrapolates', () => {
  const inside = { pass: true, failed: [], outside: [], coverage: 0.9, extrapolated: false, verdict: 'pass' };
  assert.equal(headline(inside, null).tone, 'pass');
  const extrapolated = { ...inside, outside: [{ name: 'm' }], extrapolated: true, verdict: 'uncertain' };
  const h = headline(extrapolated, null);
  assert.equal(h.tone, 'uncertain');
  assert.match(h.text, /extrapolated: no claim/);
  assert.equal(intervalVerdict(extrapolated).verdict, 'uncertain');
  assert.equal(headline({ ...inside, verdict: 'uncertain' }, null).tone, 'uncertain');
  assert.equal(headline({ ...extrapolated, pass: false, failed: ['peak'] }, null).tone, 'fail');
  // Without a calibration (no verdict) an extrapolated pass is not green either.
  assert.equal(headline({ pass: true, failed: [], outside: [{ name: 'm' }] }, null).tone, 'uncertain');
});

test('range labels never show a bound outside the range they name', () => {
  assert.equal(fmtBound(31104, 'min'), '31104');
  assert.equal(fmtBound(46656, 'max'), '46656');
  assert.equal(fmtBound(2e6, 'max'), '2e6');
  assert.equal(fmtBound(0.5, 'min'), '0.5');
  for (const [v, side] of [[0.123456789, 'min'], [0.123456789, 'max'], [1234567.891, 'min'], [1234567.891, 'max'],
    [-0.00123456789, 'min'], [-0.00123456789, 'max']]) {
    const shown = Number(fmtBound(v, side));
    assert.ok(side === 'min' ? shown >= v : shown <= v, `${v} (${side}) shown as ${shown}`);
    assert.ok(Math.abs(shown - v) <= 1e-5 * Math.abs(v), `${v} (${side}) shown as ${shown}`);
  }
});

test('compact curves decode to the float32 values and bands to the curve minus and plus the half-width', () => {
  // The server's encoding (crates/explore/src/encoding.rs): 1, 2, 3, 5 predicted as 0, 1, 3, 4.
  assert.deepEqual(fromF32Base64('AAAAAAAAAACAgAAgP38AAA=='), [1, 2, 3, 5]);
  assert.deepEqual(fromF32Base64(''), []);
  // An encoder written from the docs, for the rest.
  const dv = new DataView(new ArrayBuffer(4));
  const bits = (x) => { dv.setFloat32(0, x, true); return dv.getUint32(0, true); };
  const b64 = (xs) => {
    const v = xs.map(Math.fround);
    const n = v.length;
    const planes = Buffer.alloc(4 * n);
    v.forEach((x, i) => {
      const p = i === 0 ? 0 : i === 1 ? v[0] : Math.fround(2 * v[i - 1] - v[i - 2]);
      const w = (bits(x) ^ (Number.isFinite(p) ? bits(p) : 0)) >>> 0;
      for (let j = 0; j < 4; j++) planes[j * n + i] = (w >>> (8 * j)) & 255;
    });
    return planes.toString('base64');
  };
  const xs = [1, -2.5, 0.1, 3.4e38, 3.4e38, -3.4e38, 1e-30, 0];
  assert.deepEqual(fromF32Base64(b64(xs)), xs.map(Math.fround));
  const answer = decodeAnswer({
    encoding: 'f32', t: [0, 1], indices: [],
    channels: { x: b64([1, 2]), e: b64([0.5, 0.25]) }, bands: { x: { half: b64([0.5, 0.25]) } },
  });
  assert.deepEqual(answer.channels, { x: [1, 2], e: [0.5, 0.25] });
  assert.deepEqual(answer.bands, { x: { lo: [0.5, 1.75], hi: [1.5, 2.25] } });
  const json = { encoding: 'json', channels: { x: [1] }, bands: {} };
  assert.equal(decodeAnswer(json), json);
});

test('a solve says inside or outside for every banded channel, plotted or not', () => {
  const pred = { coverage: 0.9, bands: {} };
  const solve = { coverage: 0.9, inside: { x: { inside: false, fraction_inside: 0.75 } } };
  assert.equal(channelInside(pred, solve, 'x'), 0.75);
  assert.equal(channelInside(pred, solve, 'y'), null);
});

test('a solve without a prediction of its design says so, with the solver\'s verdict', () => {
  const text = solvedWithoutPrediction({ pass: false, failed: ['peak'], solve_ms: 12 }, 'server fault (HTTP 500)');
  assert.match(text, /^solver in 12 ms: fails peak\./);
  assert.match(text, /prediction of this design failed \(server fault \(HTTP 500\)\)/);
});

/** A local server: /refuse answers 400 with the API's error body, /busy 429, /hang never. */
async function server() {
  const seen = { closed: 0, busy: 0 };
  const srv = http.createServer((req, res) => {
    if (req.url === '/refuse') {
      res.writeHead(400, { 'Content-Type': 'application/json' });
      res.end(JSON.stringify({ error: '`design.m` = -1 is out of range', field: 'design.m', allowed: '> 0' }));
    } else if (req.url === '/busy') {
      seen.busy += 1;
      res.writeHead(429, { 'Content-Type': 'application/json', 'Retry-After': '5' });
      res.end(JSON.stringify({ error: 'solver busy', retry_after_s: 5 }));
    } else {
      req.on('close', () => { seen.closed += 1; });
    }
  });
  await new Promise((resolve) => srv.listen(0, '127.0.0.1', resolve));
  return { srv, seen, url: (p) => `http://127.0.0.1:${srv.address().port}${p}` };
}

test('a refused request throws the server\'s words; an aborted one closes its connection', async () => {
  const { srv, seen, url } = await server();
  try {
    await assert.rejects(api('POST', url('/refuse'), { design: { m: -1 } }), (err) => err instanceof ApiError
      && err.status === 400 && err.field === 'design.m' && err.allowed === '> 0');
    const abort = new AbortController();
    const pending = api('POST', url('/hang'), { design: {} }, { signal: abort.signal });
    await new Promise((resolve) => setTimeout(resolve, 100));
    abort.abort();
    await assert.rejects(pending, (err) => isAbort(err));
    for (let i = 0; i < 50 && !seen.closed; i++) await new Promise((resolve) => setTimeout(resolve, 20));
    assert.equal(seen.closed, 1, 'the server saw the connection close');
    // Aborted during the wait a 429 asked for: no retry.
    const abort2 = new AbortController();
    const waits = [];
    const busy = postRetryingOnce(url('/busy'), {}, { signal: abort2.signal, onWait: (s) => waits.push(s) });
    setTimeout(() => abort2.abort(), 50);
    await assert.rejects(busy, (err) => isAbort(err));
    assert.equal(seen.busy, 1, 'retried after the abort');
    assert.equal(waits[0], 5);
  } finally {
    srv.closeAllConnections();
    srv.close();
  }
});
