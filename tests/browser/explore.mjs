#!/usr/bin/env node
// The design explorer in a real browser: Chromium (Debian's, driven by the pinned
// playwright-core) does what a user would do on the page `explore` serves, screenshots each
// step, and writes what it saw for tests/explore/browser.rs to check against the real
// `predict` and `simulate` outputs.
//
//   node tests/browser/explore.mjs URL OUTDIR      (or EXPLORE_URL, EXPLORE_OUT)
//
// Writes into OUTDIR: step-N-NAME.png (full-page screenshots), design.yaml (the downloaded
// design) and results.json. Env: CHROMIUM (default /usr/bin/chromium); EXPLORE_BENCH=1 also
// measures slider release -> redrawn plots (window.explorerMetrics) over EXPLORE_BENCH_MOVES
// (default 30) slider moves and prints p50/p99. Exits nonzero with the reason on any failure,
// a missing browser or Playwright included: it never skips.

import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';

const url = process.argv[2] || process.env.EXPLORE_URL;
const outDir = process.argv[3] || process.env.EXPLORE_OUT;
const chromiumPath = process.env.CHROMIUM || '/usr/bin/chromium';
const bench = process.env.EXPLORE_BENCH === '1';
const benchMoves = Number(process.env.EXPLORE_BENCH_MOVES || 30);

const TIMEOUT_MS = 120_000;
const ARGS = ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
  '--disable-background-networking', '--disable-component-update', '--disable-sync'];

function fail(msg) {
  console.error(`explore.mjs: FAILED: ${msg}`);
  process.exit(1);
}

if (!url || !outDir) fail('usage: node tests/browser/explore.mjs URL OUTDIR (or EXPLORE_URL, EXPLORE_OUT)');
if (!fs.existsSync(chromiumPath)) {
  fail(`no Chromium at ${chromiumPath}: install Debian's chromium (apt-get install chromium), `
    + 'or point CHROMIUM at a Chromium binary');
}

let chromium;
try {
  ({ chromium } = await import('playwright-core'));
} catch (e) {
  fail(`playwright-core is not installed (${e.message.split('\n')[0]}): run \`npm ci --prefix tests/browser\``);
}

fs.mkdirSync(outDir, { recursive: true });
const results = { url, chromium: chromiumPath, steps: [], consoleErrors: [] };
const profileDir = fs.mkdtempSync(path.join(os.tmpdir(), 'pino-explore-chromium-'));
let context = null;

/** Throws (with the page's error box, when shown) unless `cond`. */
function check(cond, msg) {
  if (!cond) throw new Error(msg);
}

async function main() {
  try {
    context = await chromium.launchPersistentContext(profileDir, {
      executablePath: chromiumPath,
      headless: true,
      args: ARGS,
      viewport: { width: 1400, height: 1000 },
      acceptDownloads: true,
      timeout: 60_000,
    });
  } catch (e) {
    throw new Error(`Chromium (${chromiumPath}) did not start: ${e.message}\n`
      + "install Debian's chromium (apt-get install chromium)");
  }
  context.setDefaultTimeout(TIMEOUT_MS);
  const page = context.pages()[0] || await context.newPage();
  results.browserVersion = context.browser() ? context.browser().version() : null;

  // Console errors fail the run, except the browser's own line for a request the page
  // purposely sent that was refused (400: invalid input, 429: solver busy), and those a step
  // provokes on purpose (`tolerated`: a server fault it fakes).
  const tolerated = [];
  page.on('console', (msg) => {
    if (msg.type() !== 'error') return;
    const text = msg.text();
    if (/Failed to load resource: the server responded with a status of (400|429)\b/.test(text)) return;
    if (tolerated.some((re) => re.test(text))) return;
    results.consoleErrors.push(text);
  });
  page.on('pageerror', (err) => results.consoleErrors.push(`uncaught: ${err.message}`));

  let stepNo = 0;
  async function step(name, fn) {
    stepNo += 1;
    const t0 = Date.now();
    const file = `step-${stepNo}-${name}.png`;
    try {
      await fn();
    } catch (e) {
      await page.screenshot({ path: path.join(outDir, file.replace('.png', '-FAILED.png')), fullPage: true })
        .catch(() => {});
      throw new Error(`step ${stepNo} (${name}): ${e.message}${await errorBox()}`);
    }
    await page.screenshot({ path: path.join(outDir, file), fullPage: true });
    results.steps.push({ name, screenshot: file, ms: Date.now() - t0 });
    console.log(`explore.mjs: step ${stepNo} ${name} ok (${Date.now() - t0} ms) -> ${file}`);
  }

  async function errorBox() {
    const text = await page.evaluate(() => {
      const box = document.querySelector('#error');
      return box && !box.hidden ? box.textContent.replace(/\s+/g, ' ').trim() : '';
    }).catch(() => '');
    return text ? `\nthe page shows an error: ${text}` : '';
  }

  async function expectNoError() {
    const text = await errorBox();
    check(!text, `unexpected error box${text}`);
  }

  const counter = (name) => page.evaluate((n) => Number(document.body.dataset[n] || 0), name);

  /** Waits until body[data-NAME] reaches `n` and the page is idle. */
  async function waitCounter(name, n) {
    await page.waitForFunction(([k, v]) => Number(document.body.dataset[k] || 0) >= v
      && document.body.dataset.state === 'idle', [name, n], { timeout: TIMEOUT_MS });
  }

  /** What every chart plots: {GROUP: {labels: [...], data: [[x...], [y...]...]}}. */
  const plotted = () => page.evaluate(() => {
    const out = {};
    for (const [key, u] of Object.entries(window.explorerCharts || {})) {
      out[key] = {
        labels: u.series.map((s) => s.label),
        data: u.data.map((col) => Array.from(col)),
      };
    }
    return out;
  });

  /**
   * The band pixels of every chart: pixels of its canvas whose colour is one band's fill alone
   * (the channel's colour at window.explorerBandAlpha over the transparent canvas).
   */
  const bandPixels = () => page.evaluate(() => {
    const alpha = Math.round(window.explorerBandAlpha * 255);
    const out = {};
    for (const [key, u] of Object.entries(window.explorerCharts || {})) {
      const bands = u.explorerBands || [];
      const canvas = u.ctx.canvas;
      const img = u.ctx.getImageData(0, 0, canvas.width, canvas.height).data;
      const colours = bands.map((b) => {
        const n = parseInt(b.color.slice(1), 16);
        return [(n >> 16) & 255, (n >> 8) & 255, n & 255];
      });
      let pixels = 0;
      for (let i = 0; i < img.length; i += 4) {
        if (Math.abs(img[i + 3] - alpha) > 3) continue;
        if (colours.some((c) => Math.abs(img[i] - c[0]) <= 8 && Math.abs(img[i + 1] - c[1]) <= 8
          && Math.abs(img[i + 2] - c[2]) <= 8)) pixels += 1;
      }
      out[key] = { bands: bands.map((b) => b.channel), pixels, canvas: [canvas.width, canvas.height] };
    }
    return out;
  });

  /** The indices table as shown: per index its interval text and verdict badge. */
  const shownIntervals = () => page.$$eval('#indices tbody tr', (rows) => rows.map((r) => ({
    index: r.dataset.index,
    interval: (r.querySelector('td.interval') || {}).textContent || null,
    verdict: (r.querySelector('td.verdict-cell .badge') || {}).textContent || null,
    inside: (r.querySelector('td.solver .inside-mark') || {}).textContent || null,
  })));

  const state = () => page.evaluate(() => JSON.parse(JSON.stringify({
    design: window.explorerState.design,
    excitation: window.explorerState.excitation,
  })));

  /**
   * What a reader sees at a glance: whether the side panel scrolls on its own, whether the
   * excitation and compare cards are in the window, each group's channel colours, each axis
   * label's box against its chart's and each y axis's tick labels.
   */
  const readability = () => page.evaluate(() => {
    const panel = document.querySelector('.panel.left');
    const inView = (sel) => {
      const n = document.querySelector(sel);
      if (!n || n.hidden) return [sel, true];
      const b = n.getBoundingClientRect();
      return [sel, b.top >= 0 && b.bottom <= window.innerHeight + 0.5];
    };
    const groupColours = [...document.querySelectorAll('.chart-section')].map((sec) => [
      sec.dataset.group,
      [...sec.querySelectorAll('.channel .swatch')].map((w) => getComputedStyle(w).backgroundColor),
    ]);
    const axisLabels = [];
    const yTicks = [];
    for (const [key, u] of Object.entries(window.explorerCharts || {})) {
      const root = u.root.getBoundingClientRect();
      u.root.querySelectorAll('.u-axis .u-label').forEach((l) => {
        const b = l.getBoundingClientRect();
        axisLabels.push({
          chart: key, text: l.textContent,
          inside: b.left >= root.left - 0.5 && b.right <= root.right + 0.5
            && b.top >= root.top - 0.5 && b.bottom <= root.bottom + 0.5
            && l.scrollWidth <= l.clientWidth + 1,
        });
      });
      u.axes.forEach((a, i) => {
        if (i > 0) yTicks.push([`${key}.${i}`, (u.explorerTicks || {})[i] || []]);
      });
    }
    return {
      panelScrolls: panel.scrollHeight > panel.clientHeight + 1,
      cardsInView: [inView('#excitation-box'), inView('#pin'), inView('#unpin')],
      groupColours, axisLabels, yTicks,
    };
  });

  /** Drags the slider of `param` to `fraction` of its track, as a mouse would. */
  async function dragSlider(param, fraction) {
    const slider = page.locator(`.param[data-param="${param}"] input[type=range]`);
    await slider.scrollIntoViewIfNeeded();
    const box = await slider.boundingBox();
    check(box, `the slider of ${param} is not visible`);
    const cur = await slider.evaluate((s) => (Number(s.value) - Number(s.min)) / (Number(s.max) - Number(s.min)));
    const y = box.y + box.height / 2;
    // The thumb travels between half a thumb (about 8 px) from either end.
    const at = (f) => box.x + 8 + f * (box.width - 16);
    await page.mouse.move(at(cur), y);
    await page.mouse.down();
    await page.mouse.move(at(fraction), y, { steps: 6 });
    await page.mouse.up();
  }

  /** Types `value` into the number field of `param` and leaves it, as a user would. */
  async function typeValue(param, value) {
    const n = await counter('predictions');
    const field = page.locator(`.param[data-param="${param}"] input[type=number]`);
    await field.scrollIntoViewIfNeeded();
    await field.click({ clickCount: 3 });
    await field.fill(String(value));
    await field.press('Tab');
    await waitCounter('predictions', n + 1);
    await expectNoError();
  }

  // ---- 1. the page loads the model: one row per parameter ------------------------------
  let summary;
  await step('loaded', async () => {
    await page.goto(url, { waitUntil: 'load' });
    await waitCounter('predictions', 1);
    await expectNoError();
    summary = await page.evaluate(() => window.explorerState.summary);
    check(summary && Array.isArray(summary.parameters), 'window.explorerState.summary has no parameters');
    results.parameters = await page.$$eval('#params .param', (rows) => rows.map((r) => r.dataset.param));
    results.parameterLabels = await page.$$eval('#params .param .param-name', (ls) => ls.map((l) => l.textContent));
    check(results.parameters.length > 0, 'no parameter rows');
    const charts = await plotted();
    check(Object.keys(charts).length > 0, 'no chart drawn after the first prediction');
    results.readability = await readability();
    const r = results.readability;
    check(r.panelScrolls === false, `the side panel scrolls on its own: ${JSON.stringify(r)}`);
    check(r.cardsInView.every(([, inView]) => inView), `cards not in view at 1400 x 1000: ${JSON.stringify(r.cardsInView)}`);
    const repeated = r.groupColours.filter(([, colours]) => new Set(colours).size !== colours.length);
    check(repeated.length === 0, `colours repeated within a group: ${JSON.stringify(repeated)}`);
    const clipped = r.axisLabels.filter((a) => !a.inside);
    check(clipped.length === 0, `axis labels clipped: ${JSON.stringify(clipped)}`);
    const fewTicks = r.yTicks.filter(([, ticks]) => ticks.filter((t) => t !== '').length < 2);
    check(fewTicks.length === 0, `y axes with fewer than 2 ticks: ${JSON.stringify(fewTicks)}`);
    // The range labels never show a bound outside the range they name (31100 for 31104).
    const labels = await page.$$eval('#params .param', (rows) => rows.map((row) => [row.dataset.param,
      row.querySelector('.param-range').firstChild.textContent]));
    const outsideLabels = labels.filter(([name, text]) => {
      const p = summary.parameters.find((q) => q.name === name);
      const [lo, hi] = text.split('…').map((x) => Number(x.trim()));
      return !(lo >= p.min && hi <= p.max && lo <= hi);
    });
    check(outsideLabels.length === 0, `range labels outside their ranges: ${JSON.stringify(outsideLabels)}`);
    results.rangeLabels = labels;
  });

  // ---- 2. choose the test sample: the design becomes the sample's ------------------------
  await step('test-sample', async () => {
    const samples = (summary.excitation && summary.excitation.test_samples) || [];
    check(samples.length > 0, 'the model summary lists no test sample');
    const sample = samples[0];
    const designBefore = (await state()).design;
    let n = await counter('predictions');
    await page.selectOption('select#excitation', `test:${sample.sample_id}`);
    await waitCounter('predictions', n + 1);
    await expectNoError();
    // The fields show the sample's values rounded to their slider's step (the design keeps
    // them exactly), and the replaced design can be put back.
    const fields = await page.$$eval('#params .param', (rows) => rows.map((r) => {
      const range = r.querySelector('input[type=range]');
      const number = r.querySelector('input[type=number]');
      return { name: r.dataset.param, shown: number.value, step: Number(range.step),
        fits: number.scrollWidth <= number.clientWidth + 1 };
    }));
    for (const f of fields) {
      const exact = sample.design[f.name];
      check(exact == null || Math.abs(Number(f.shown) - exact) <= f.step / 2 * (1 + 1e-9),
        `${f.name} shows ${f.shown}, more than half a slider step (${f.step}) from ${exact}`);
      const decimals = (f.shown.split('.')[1] || '').length;
      check(decimals <= Math.max(0, Math.ceil(-Math.log10(f.step))),
        `${f.name} shows ${f.shown}: more decimals than its slider's step ${f.step}`);
    }
    const undo = page.locator('#undo-design');
    check(await undo.isVisible(), 'no undo offered after the test sample replaced the design');
    n = await counter('predictions');
    await undo.click();
    await waitCounter('predictions', n + 1);
    const undone = (await state()).design;
    check(JSON.stringify(undone) === JSON.stringify(designBefore),
      `undo gave ${JSON.stringify(undone)}, not the design before ${JSON.stringify(designBefore)}`);
    check(!(await undo.isVisible()), 'the undo is still offered after it was used');
    results.testSampleFields = { fields, undone: true };
    // Back to the sample's design for the steps that follow.
    n = await counter('predictions');
    await page.selectOption('select#excitation', 'seed');
    await waitCounter('predictions', n + 1);
    n = await counter('predictions');
    await page.selectOption('select#excitation', `test:${sample.sample_id}`);
    await waitCounter('predictions', n + 1);
    await expectNoError();
    const s = await state();
    check(s.excitation && s.excitation.kind === 'test' && s.excitation.sample_id === sample.sample_id,
      `excitation is ${JSON.stringify(s.excitation)}, not test sample ${sample.sample_id}`);
    for (const [k, v] of Object.entries(sample.design || {})) {
      check(s.design[k] === v, `after choosing test sample ${sample.sample_id}, ${k} = ${s.design[k]}, not the sample's ${v}`);
    }
    results.sample = { sample_id: sample.sample_id, design: sample.design };
  });

  // ---- 3. the calibrated bands, intervals and verdicts -----------------------------------
  await step('bands', async () => {
    check(await page.evaluate(() => document.body.dataset.calibrated) === 'true',
      `the page found no calibration: ${await page.textContent('#calibration-note')}`);
    const pred = await page.evaluate(() => window.explorerState.prediction);
    check(pred.coverage === 0.9, `the first prediction's coverage is ${pred.coverage}, not 0.9`);
    const pixels = await bandPixels();
    const groups = Object.keys(pixels).filter((k) => k !== 'sweep' && k !== 'excitation');
    check(groups.length > 0, 'no response chart');
    for (const g of groups) {
      check(pixels[g].bands.length > 0, `the ${g} chart draws no band`);
      check(pixels[g].pixels > 200, `the ${g} chart shows only ${pixels[g].pixels} band pixels`);
    }
    const verdict = (await page.textContent('#interval-verdict')).trim();
    check(/^at 90 %: (pass|uncertain|fail)/.test(verdict), `the verdict reads ${JSON.stringify(verdict)}`);
    const rows = await shownIntervals();
    check(rows.every((r) => r.interval && r.interval.startsWith('[')), `rows without an interval: ${JSON.stringify(rows)}`);
    check(rows.some((r) => ['pass', 'uncertain', 'fail'].includes(r.verdict)), `no verdict badge: ${JSON.stringify(rows)}`);
    const options = await page.$$eval('#coverage option', (os) => os.map((o) => ({
      value: o.value, disabled: o.disabled, title: o.title,
    })));
    check(options.map((o) => o.value).join() === '0.8,0.9,0.95', `levels ${JSON.stringify(options)}`);
    check(options[2].disabled && /not supported/.test(options[2].title),
      `0.95 (10 calibration samples) is not disabled with its reason: ${JSON.stringify(options[2])}`);
    results.bands = { pixels, verdict, rows, options, prediction_verdict: pred.verdict };
  });

  // ---- 4. switch the level: the bands and intervals follow --------------------------------
  await step('level', async () => {
    const before = await page.evaluate(() => window.explorerState.prediction);
    const n = await counter('predictions');
    await page.selectOption('#coverage', '0.8');
    await waitCounter('predictions', n + 1);
    await expectNoError();
    const after = await page.evaluate(() => window.explorerState.prediction);
    check(after.coverage === 0.8, `after choosing 0.8 the prediction's coverage is ${after.coverage}`);
    const verdict = (await page.textContent('#interval-verdict')).trim();
    check(verdict.startsWith('at 80 %'), `the verdict reads ${JSON.stringify(verdict)}`);
    const rows = await shownIntervals();
    const narrower = after.indices.filter((ix, k) => ix.hi - ix.lo < before.indices[k].hi - before.indices[k].lo);
    check(narrower.length > 0, 'no interval narrowed from 0.9 to 0.8');
    const shown = await page.evaluate(() => Object.fromEntries(Object.entries(window.explorerCharts)
      .map(([k, u]) => [k, (u.explorerBands || []).map((b) => [b.channel, b.hi[0] - b.lo[0]])])));
    const pixels = await bandPixels();
    const groups = Object.keys(pixels).filter((k) => k !== 'sweep' && k !== 'excitation');
    for (const g of groups) check(pixels[g].pixels > 200, `the ${g} chart shows only ${pixels[g].pixels} band pixels at 0.8`);
    results.level = {
      verdict, rows, pixels, shown, coverage: after.coverage,
      widths_09: before.indices.map((ix) => ix.hi - ix.lo), widths_08: after.indices.map((ix) => ix.hi - ix.lo),
    };
    // Back to 0.9 for the following steps.
    const m = await counter('predictions');
    await page.selectOption('#coverage', '0.9');
    await waitCounter('predictions', m + 1);
    await expectNoError();
  });

  // ---- 5. "Solve exactly": the solver's curves overlay the prediction --------------------
  await step('solve', async () => {
    const n = await counter('solves');
    const before = await state();
    await page.click('#solve');
    await waitCounter('solves', n + 1);
    await expectNoError();
    const charts = await plotted();
    const overlaid = Object.values(charts).some((c) => c.labels.some((l) => / \(solver\)$/.test(l)));
    check(overlaid, 'no "(solver)" series in the charts after the solve');
    const answer = await page.evaluate(() => {
      const s = window.explorerState.solve;
      return s && { design: s.design, excitation: s.excitation, solve_ms: s.solve_ms, errors: s.errors };
    });
    check(answer, 'window.explorerState.solve is empty after the solve');
    const status = await page.textContent('#solve-status');
    // Inside / outside marks: per channel beside its error, per index beside the solver value.
    const channelMarks = await page.$$eval('.channel .inside-mark', (ms) => ms.map((m) => m.textContent));
    check(channelMarks.length > 0, 'no channel says whether the solver curve lies inside its band');
    // Every banded channel says it, plotted or not (the excitations are exact inputs).
    const unmarked = await page.$$eval('.chart-section:not(.group-excitation) .channel',
      (ls) => ls.filter((l) => !l.querySelector('.inside-mark')).map((l) => l.dataset.channel));
    check(unmarked.length === 0, `banded channels without an inside mark: ${JSON.stringify(unmarked)}`);
    const rows = await shownIntervals();
    check(rows.every((r) => r.inside), `indices without an inside mark: ${JSON.stringify(rows)}`);
    const inside = await page.evaluate(() => window.explorerState.solve.index_inside);
    for (const r of rows) {
      check(r.inside.includes(inside[r.index] ? 'inside' : 'outside'),
        `${r.index}: the page says ${r.inside}, the answer ${inside[r.index]}`);
    }
    // The headline verdict follows the solver, the surrogate's beside it; errors above 10 %
    // stand out, and only those.
    const headline = await page.evaluate(() => {
      const v = document.querySelector('#verdict');
      return { text: v.textContent, source: v.dataset.source, pass: v.dataset.pass };
    });
    const solvedPass = await page.evaluate(() => window.explorerState.solve.pass);
    check(headline.source === 'solver' && headline.text.startsWith('solver: ')
      && headline.text.includes('; surrogate: ') && headline.pass === String(solvedPass),
    `the headline verdict after the solve: ${JSON.stringify(headline)} (solver pass: ${solvedPass})`);
    const errorCells = await page.$$eval('#indices td.error', (cells) => cells.map((c) => [c.textContent, c.classList.contains('large-error')]));
    const misMarked = errorCells.filter(([t, large]) => Number.isFinite(parseFloat(t)) && (Math.abs(parseFloat(t)) > 10) !== large);
    check(errorCells.length > 0 && misMarked.length === 0, `index errors marked wrongly (> 10 % must stand out): ${JSON.stringify(misMarked)}`);
    const header = await page.$$eval('#indices thead th', (ths) => ths.map((t) => t.textContent));
    check(header[2] === 'surrogate', `the index value column is headed ${JSON.stringify(header[2])}`);
    // Each chart's key says which line style is the surrogate's and which the solver's.
    const keys = await page.$$eval('.chart-section', (secs) => secs.map((sec) => [sec.dataset.group,
      [...sec.querySelectorAll('.line-key .key-item')].map((k) => [k.dataset.kind,
        getComputedStyle(k.querySelector('.key-line')).borderTopStyle])]));
    const badKeys = keys.filter(([, items]) => JSON.stringify(items.slice(0, 2))
      !== JSON.stringify([['surrogate', 'solid'], ['solver', 'dashed']]));
    check(badKeys.length === 0, `charts without a surrogate (solid) / solver (dashed) key: ${JSON.stringify(badKeys)}`);
    results.solve = { design: before.design, excitation: before.excitation, answer, status, charts, channelMarks, rows, headline, errorCells, keys };
  });

  // ---- 6. move a slider: the curves change ----------------------------------------------
  const sliderParam = summary.parameters[0].name;
  await step('slider', async () => {
    const before = await plotted();
    const designBefore = (await state()).design;
    const n = await counter('predictions');
    const p = summary.parameters[0];
    const cur = (designBefore[p.name] - p.min) / (p.max - p.min);
    await dragSlider(p.name, cur < 0.5 ? 0.85 : 0.15);
    await waitCounter('predictions', n + 1);
    await expectNoError();
    const after = await plotted();
    const s = await state();
    check(s.design[p.name] !== designBefore[p.name],
      `dragging the ${p.name} slider left the design at ${designBefore[p.name]}`);
    const shown = Number(await page.inputValue(`.param[data-param="${p.name}"] input[type=number]`));
    check(shown === s.design[p.name], `the ${p.name} field shows ${shown}, the design has ${s.design[p.name]}`);
    // The curves changed (the first series of each chart is a prediction).
    let changed = false;
    for (const [g, c] of Object.entries(after)) {
      if (g === 'sweep' || !before[g]) continue;
      const a = c.data[1];
      const b = before[g].data[1];
      if (a.some((v, i) => v !== b[i])) changed = true;
    }
    check(changed, `no plotted curve changed after moving ${p.name} from ${designBefore[p.name]} to ${s.design[p.name]}`);
    const overlay = Object.values(after).some((c) => c.labels.some((l) => / \(solver\)$/.test(l)));
    check(!overlay, 'the solver overlay of the previous design is still shown');
    results.slider = {
      param: p.name, from: designBefore[p.name], to: s.design[p.name],
      design: s.design, excitation: s.excitation, changed, charts: after,
    };
  });

  // ---- 6b. drag a slider without letting go: the plots follow while it moves ------------
  await step('drag-live', async () => {
    const p = summary.parameters[0];
    const slider = page.locator(`.param[data-param="${p.name}"] input[type=range]`);
    await slider.scrollIntoViewIfNeeded();
    const box = await slider.boundingBox();
    const y = box.y + box.height / 2;
    const at = (f) => box.x + 8 + f * (box.width - 16);
    const cur = await slider.evaluate((s) => (Number(s.value) - Number(s.min)) / (Number(s.max) - Number(s.min)));
    await page.mouse.move(at(cur), y);
    await page.mouse.down();
    const seen = [];
    try {
      for (const f of [0.3, 0.5, 0.7]) {
        const n = await counter('predictions');
        await page.mouse.move(at(f), y, { steps: 3 });
        await page.waitForFunction((k) => Number(document.body.dataset.predictions || 0) > k, n, { timeout: 20_000 })
          .catch(() => { throw new Error(`no prediction drawn while the slider is held at ${f} of its track`); });
        seen.push(await page.evaluate(() => window.explorerState.prediction.design));
      }
    } finally {
      await page.mouse.up();
    }
    const moved = new Set(seen.map((d) => d[p.name]));
    check(moved.size === seen.length, `the predictions drawn during the drag are of one position: ${JSON.stringify([...moved])}`);
    await page.waitForFunction(() => document.body.dataset.state === 'idle');
    await expectNoError();
    const s = await state();
    const drawn = await page.evaluate(() => window.explorerState.prediction.design);
    check(drawn[p.name] === s.design[p.name], `after the release the plots show ${drawn[p.name]}, the design is ${s.design[p.name]}`);
    results.dragLive = { param: p.name, during: [...moved], released: s.design[p.name] };
  });

  // ---- 7. type a value outside the training range: the flag ------------------------------
  await step('outside', async () => {
    const p = summary.parameters[Math.min(1, summary.parameters.length - 1)];
    const value = Number((p.max + 0.5 * (p.max - p.min)).toPrecision(6));
    const previous = (await state()).design[p.name];
    await typeValue(p.name, value);
    const banner = page.locator('#outside-banner');
    check(await banner.isVisible(), `#outside-banner is hidden after typing ${p.name} = ${value}`);
    const rowFlag = page.locator(`.param[data-param="${p.name}"] .outside-flag`);
    check(await rowFlag.isVisible(), `the ${p.name} row shows no outside flag`);
    const s = await state();
    const outside = await page.evaluate(() => window.explorerState.prediction.outside);
    // Extrapolated, the surrogate's headline is never a green pass beside "no coverage claim".
    const headline = await page.evaluate(() => {
      const v = document.querySelector('#verdict');
      return { text: v.textContent, classes: [...v.classList] };
    });
    check(!headline.classes.includes('pass'), `a green headline while extrapolating: ${JSON.stringify(headline)}`);
    results.outside = {
      headline,
      param: p.name, value, previous, design: s.design,
      banner: (await banner.textContent()).trim(),
      row_flag: (await rowFlag.textContent()).trim(),
      row_class_outside: await page.locator(`.param[data-param="${p.name}"]`).evaluate((r) => r.classList.contains('outside')),
      answer_outside: outside,
    };
  });

  // ---- 7b. an invalid input: named in the user's words, the row marked, results stale ----
  await step('invalid', async () => {
    const p = summary.parameters.find((q) => q.name === 'm_c') || summary.parameters[0];
    const previous = (await state()).design[p.name];
    const field = page.locator(`.param[data-param="${p.name}"] input[type=number]`);
    await field.scrollIntoViewIfNeeded();
    await field.click({ clickCount: 3 });
    await field.fill('-1');
    await field.press('Tab');
    await page.waitForFunction(() => window.explorerState.stale === true
      && !document.querySelector('#error').hidden && document.body.dataset.state === 'idle');
    const box = page.locator('#error');
    const shown = {
      message: (await page.locator('#error .error-message').textContent()).trim(),
      field: await box.evaluate((b) => b.dataset.field),
      allowed: (await page.locator('#error .error-allowed').textContent()).trim(),
      rowInvalid: await page.locator(`.param[data-param="${p.name}"]`).evaluate((r) => r.classList.contains('invalid')),
      staleBanner: await page.locator('#stale-banner').isVisible(),
      indicesOpacity: Number(await page.locator('#indices-card').evaluate((c) => getComputedStyle(c).opacity)),
      chartsOpacity: Number(await page.locator('#charts').evaluate((c) => getComputedStyle(c).opacity)),
    };
    check(shown.field === `design.${p.name}`, `the error names ${shown.field}, not design.${p.name}`);
    check(shown.message.includes(`design.${p.name}\` = -1`), `the message does not quote the typed value: ${shown.message}`);
    check(shown.rowInvalid, `the ${p.name} row is not marked invalid`);
    check(shown.staleBanner && shown.indicesOpacity < 1 && shown.chartsOpacity < 1,
      `the old results are not marked out of date: ${JSON.stringify(shown)}`);
    // Fixing the input answers again and lifts the mark.
    await typeValue(p.name, previous);
    const cleared = await page.evaluate(() => !window.explorerState.stale
      && document.querySelector('#stale-banner').hidden && !document.querySelector('.param.invalid'));
    check(cleared, 'the out-of-date mark stayed after the input was fixed');
    results.invalid = { param: p.name, previous, ...shown, cleared };
  });

  // ---- 7c. an invalid seed: the results greyed as for any refused input -------------------
  await step('invalid-seed', async () => {
    const sampleValue = await page.inputValue('select#excitation');
    let n = await counter('predictions');
    await page.selectOption('select#excitation', 'seed');
    await waitCounter('predictions', n + 1);
    const seed = page.locator('#excitation-seed');
    await seed.click({ clickCount: 3 });
    await seed.fill('-3');
    await seed.press('Tab');
    await page.waitForFunction(() => !document.querySelector('#error').hidden);
    const shown = {
      field: await page.locator('#error').evaluate((b) => b.dataset.field),
      message: (await page.locator('#error .error-message').textContent()).trim(),
      stale: await page.evaluate(() => window.explorerState.stale),
      staleBanner: await page.locator('#stale-banner').isVisible(),
      chartsOpacity: Number(await page.locator('#charts').evaluate((c) => getComputedStyle(c).opacity)),
    };
    check(shown.field === 'excitation.seed', `the error names ${shown.field}`);
    check(shown.stale && shown.staleBanner && shown.chartsOpacity < 1,
      `the results are not marked out of date after a negative seed: ${JSON.stringify(shown)}`);
    n = await counter('predictions');
    await seed.fill('1');
    await seed.press('Tab');
    await waitCounter('predictions', n + 1);
    check(!(await page.evaluate(() => window.explorerState.stale)), 'the out-of-date mark stayed after the seed was fixed');
    // Back to the test sample, and the design before it.
    n = await counter('predictions');
    await page.selectOption('select#excitation', sampleValue);
    await waitCounter('predictions', n + 1);
    n = await counter('predictions');
    await page.click('#undo-design');
    await waitCounter('predictions', n + 1);
    await expectNoError();
    results.invalidSeed = shown;
  });

  // ---- 8. back inside the range (the flag goes), then a sweep ----------------------------
  await step('sweep', async () => {
    await typeValue(results.outside.param, results.outside.previous);
    check(!(await page.locator('#outside-banner').isVisible()),
      `#outside-banner still shows after typing ${results.outside.param} = ${results.outside.previous} back`);
    const p = summary.parameters[summary.parameters.length - 1];
    const steps = 9;
    const solvePoints = 2;
    await page.locator('#sweep').scrollIntoViewIfNeeded();
    await page.selectOption('#sweep-param', p.name);
    await page.fill('#sweep-steps', String(steps));
    await page.fill('#sweep-solve-points', String(solvePoints));
    const n = await counter('sweeps');
    await page.click('#run-sweep');
    await waitCounter('sweeps', n + 1);
    await expectNoError();
    const answer = await page.evaluate(() => window.explorerState.sweep);
    const charts = await plotted();
    check(charts.sweep, 'no sweep chart drawn');
    const pixels = await bandPixels();
    check(pixels.sweep.bands.length === 1 && pixels.sweep.pixels > 100,
      `the sweep's index curve shows no band: ${JSON.stringify(pixels.sweep)}`);
    results.sweep = {
      request: {
        parameter: p.name, steps, solve_points: solvePoints,
        from: Number(await page.inputValue('#sweep-from')), to: Number(await page.inputValue('#sweep-to')),
        index: await page.inputValue('#sweep-index'),
      },
      answer,
      chart: charts.sweep,
      band_pixels: pixels.sweep,
      status: await page.textContent('#sweep-status'),
    };
  });

  // ---- 8b. a failed sweep: the last sweep's chart stays, marked out of date ----------------
  await step('sweep-failed', async () => {
    const p = summary.parameters.find((q) => q.name === 'm_c') || summary.parameters[0];
    await page.selectOption('#sweep-param', p.name);
    await page.fill('#sweep-from', '-1');
    await page.click('#run-sweep');
    await page.waitForFunction(() => !document.querySelector('#error').hidden && document.body.dataset.state === 'idle');
    const shown = {
      error: (await page.locator('#error .error-message').textContent()).trim(),
      stale: await page.locator('#sweep').evaluate((n) => n.classList.contains('stale')),
      note: await page.locator('#sweep-stale').isVisible(),
      opacity: Number(await page.locator('#sweep-chart').evaluate((c) => getComputedStyle(c).opacity)),
      chart: !!(await page.evaluate(() => window.explorerCharts.sweep)),
    };
    check(shown.chart && shown.stale && shown.note && shown.opacity < 1,
      `the chart of the last sweep is not marked out of date after a failed one: ${JSON.stringify(shown)}`);
    await page.click('#error-dismiss');
    results.sweepFailed = shown;
  });

  // ---- 9. download the design (predict --params reads it back: browser.rs) ---------------
  await step('download', async () => {
    await page.locator('#download-design').scrollIntoViewIfNeeded();
    const [download] = await Promise.all([
      page.waitForEvent('download', { timeout: TIMEOUT_MS }),
      page.click('#download-design'),
    ]);
    check(download.suggestedFilename() === 'design.yaml',
      `the download is named ${download.suggestedFilename()}, not design.yaml`);
    const failure = await download.failure();
    check(!failure, `the download failed: ${failure}`);
    await download.saveAs(path.join(outDir, 'design.yaml'));
    await expectNoError();
    const s = await state();
    const charts = await plotted();
    delete charts.sweep;
    results.download = { file: 'design.yaml', design: s.design, excitation: s.excitation, charts };
  });

  // ---- benchmark: slider release -> redrawn plots (EXPLORE_BENCH=1) ----------------------
  if (bench) {
    const p = summary.parameters[0];
    await page.evaluate(() => performance.clearResourceTimings());
    const start = await page.evaluate(() => window.explorerMetrics.predictToRedrawMs.length);
    for (let i = 0; i < benchMoves; i++) {
      const n = await counter('predictions');
      await dragSlider(p.name, 0.1 + 0.8 * ((i * 7) % benchMoves) / benchMoves);
      await waitCounter('predictions', n + 1);
    }
    const ms = await page.evaluate((k) => window.explorerMetrics.predictToRedrawMs.slice(k), start);
    const sorted = [...ms].sort((a, b) => a - b);
    const q = (f) => sorted[Math.min(sorted.length - 1, Math.ceil(f * sorted.length) - 1)];
    // What each prediction cost on the wire (the compressed answer with its head) and
    // decoded, as the browser counts it.
    const wire = await page.evaluate(() => performance.getEntriesByType('resource')
      .filter((e) => e.name.endsWith('/api/predict'))
      .map((e) => ({ transfer: e.transferSize, body: e.encodedBodySize, decoded: e.decodedBodySize })));
    const median = (xs) => [...xs].sort((a, b) => a - b)[Math.floor(xs.length / 2)];
    results.bench = {
      moves: benchMoves, samples: ms.length, p50_ms: q(0.5), p99_ms: q(0.99), max_ms: sorted[sorted.length - 1], ms, wire,
    };
    console.log(`explore.mjs: bench: slider release -> redrawn plots over ${ms.length} moves of ${p.name}: `
      + `p50 ${q(0.5).toFixed(1)} ms, p99 ${q(0.99).toFixed(1)} ms, max ${sorted[sorted.length - 1].toFixed(1)} ms`);
    console.log(`explore.mjs: bench: ${wire.length} predictions on the wire (slider drags included): median `
      + `${median(wire.map((w) => w.transfer))} B transferred, ${median(wire.map((w) => w.decoded))} B decoded`);
  }

  /**
   * Holds the first request matching `pattern` in the browser until `release()` (later ones
   * pass), so a step can act while it is in flight. `arrived` resolves once it is held.
   */
  async function hold(pattern) {
    let release;
    const released = new Promise((resolve) => { release = resolve; });
    let arrive;
    const arrived = new Promise((resolve) => { arrive = resolve; });
    let held = false;
    const handler = async (route) => {
      if (held) { await route.continue().catch(() => {}); return; }
      held = true;
      arrive();
      await released;
      // The page may have aborted it meanwhile.
      await route.continue().catch(() => {});
    };
    await page.route(pattern, handler);
    return {
      arrived,
      release: async () => { release(); await page.unroute(pattern, handler); },
    };
  }

  /** A value of `p` inside its range, away from `current`. */
  const otherValue = (p, current, f = 0.3) => {
    const v = Number((p.min + f * (p.max - p.min)).toPrecision(6));
    return v === current ? Number((p.min + (1 - f) * (p.max - p.min)).toPrecision(6)) : v;
  };

  /** Types `value` into `param`'s number field without waiting for the prediction. */
  async function typeOnly(param, value) {
    const field = page.locator(`.param[data-param="${param}"] input[type=number]`);
    await field.scrollIntoViewIfNeeded();
    await field.click({ clickCount: 3 });
    await field.fill(String(value));
    await field.press('Tab');
  }

  const solverSeries = (charts) => Object.values(charts).some((c) => c.labels.some((l) => / \(solver\)$/.test(l)));

  // ---- 9b. "Pin as A" while the prediction of a new design is in flight: A is that design
  // with its own prediction, never the older design's prediction (issue 28: defect 1) ----------
  await step('pin-in-flight', async () => {
    await page.evaluate(() => window.scrollTo(0, 0));
    const p = summary.parameters[0];
    const before = (await state()).design;
    const oldIndices = await page.evaluate(() => window.explorerState.prediction.indices.map((i) => i.value));
    const value = otherValue(p, before[p.name]);
    const held = await hold('**/api/predict');
    const n = await counter('predictions');
    await typeOnly(p.name, value);
    await held.arrived;
    check(await page.isEnabled('#pin'), '"Pin as A" is disabled while a prediction is in flight');
    await page.click('#pin');
    await held.release();
    await waitCounter('predictions', n + 1);
    await page.waitForFunction(() => document.body.dataset.pinned === 'true', null, { timeout: 10_000 })
      .catch(() => {});
    await expectNoError();
    const shown = await page.evaluate(() => ({
      info: document.querySelector('#pin-info').textContent,
      deltas: [...document.querySelectorAll('#indices td.delta')].map((c) => c.textContent),
      a: [...document.querySelectorAll('#indices td.a')].map((c) => c.textContent),
      values: [...document.querySelectorAll('#indices td.value')].map((c) => c.textContent),
      pinned: document.body.dataset.pinned || null,
    }));
    const newIndices = await page.evaluate(() => window.explorerState.prediction.indices.map((i) => i.value));
    check(JSON.stringify(newIndices) !== JSON.stringify(oldIndices),
      `moving ${p.name} to ${value} changed no index: the step cannot tell the two predictions apart`);
    check(shown.pinned === 'true', `nothing pinned: ${JSON.stringify(shown)}`);
    check(shown.info === 'B is the same design as A.', `the pin info reads ${JSON.stringify(shown.info)}`);
    check(shown.deltas.length > 0 && shown.deltas.every((d) => d === '0'),
      `A is the design on screen but its indices differ from its prediction's (A paired with an older prediction): ${JSON.stringify(shown)}`);
    const charts = await plotted();
    for (const [g, c] of Object.entries(charts)) {
      if (g === 'sweep') continue;
      c.labels.forEach((l, j) => {
        if (!l.endsWith(' (A)')) return;
        const k = c.labels.indexOf(l.slice(0, -4));
        check(JSON.stringify(c.data[j]) === JSON.stringify(c.data[k]), `${g}: the curve of A (${l}) is not its design's prediction`);
      });
    }
    const pinned = await page.evaluate(() => window.explorerState.pinned);
    check(pinned && pinned.design[p.name] === value && pinned.prediction.design[p.name] === value,
      `explorerState.pinned: ${JSON.stringify(pinned && { design: pinned.design, predicted: pinned.prediction.design })}`);
    results.pinInFlight = { param: p.name, value, ...shown };
    await page.click('#unpin');
  });

  // ---- 9c. "Solve exactly" after the prediction failed: the solver's answer or a clear
  // message, never nothing (defect 2) ------------------------------------------------------
  await step('solve-after-failed-prediction', async () => {
    const p = summary.parameters[0];
    const previous = (await state()).design[p.name];
    const fault = /status of 500\b/;
    tolerated.push(fault);
    const refuse = (route) => route.fulfill({
      status: 500, contentType: 'application/json', body: JSON.stringify({ error: 'server fault (made by the test)' }),
    });
    await page.route('**/api/predict', refuse);
    try {
      await typeOnly(p.name, otherValue(p, previous, 0.6));
      await page.waitForFunction(() => !document.querySelector('#error').hidden
        && document.body.dataset.state === 'idle');
      const n = await counter('solves');
      await page.click('#solve');
      await page.waitForFunction((k) => (Number(document.body.dataset.solves || 0) > k
        || !document.querySelector('#error').hidden && /Solve/.test(document.querySelector('#error').textContent))
        && document.body.dataset.state === 'idle', n);
      const status = (await page.textContent('#solve-status')).trim();
      const overlaid = solverSeries(await plotted());
      check(overlaid || /prediction of this design failed/.test(status),
        `after a failed prediction the solve shows no curve and says ${JSON.stringify(status)}`);
      check(overlaid || /all limits met|fails /.test(status), `the solver's verdict is not said: ${JSON.stringify(status)}`);
      results.solveAfterFailedPrediction = { status, overlaid };
    } finally {
      await page.unroute('**/api/predict', refuse);
    }
    await typeValue(p.name, previous);
    tolerated.splice(tolerated.indexOf(fault), 1);
  });

  // ---- 9d. a design changed during a solve cancels it; its answer never shows (defect 3) ---
  await step('solve-cancelled', async () => {
    const p = summary.parameters[0];
    const previous = (await state()).design[p.name];
    const failed = [];
    const onFailed = (r) => { if (r.url().includes('/api/solve')) failed.push(r.failure() && r.failure().errorText); };
    page.on('requestfailed', onFailed);
    const held = await hold('**/api/solve');
    try {
      await page.click('#solve');
      await held.arrived;
      const n = await counter('predictions');
      await typeOnly(p.name, otherValue(p, previous, 0.45));
      await page.waitForFunction((k) => Number(document.body.dataset.predictions || 0) > k, n);
      await page.waitForTimeout(200);
    } finally {
      await held.release();
    }
    await page.waitForFunction(() => document.body.dataset.state === 'idle');
    await page.waitForTimeout(300);
    page.off('requestfailed', onFailed);
    const shown = {
      failed,
      status: (await page.textContent('#solve-status')).trim(),
      overlaid: solverSeries(await plotted()),
      solve: await page.evaluate(() => window.explorerState.solve),
    };
    check(failed.length === 1, `the solve in flight was not aborted when the design changed: ${JSON.stringify(shown)}`);
    check(!shown.overlaid && !shown.solve && !/^solver:/.test(shown.status),
      `the answer of the older design's solve is shown: ${JSON.stringify(shown)}`);
    results.solveCancelled = shown;
    await typeValue(p.name, previous);
  });

  // ---- 9e. a model without sampled parameters: the page says so and still predicts and
  // solves its one design (defect 4) ----------------------------------------------------------
  await step('no-parameters', async () => {
    const fixed = async (route) => {
      const response = await route.fetch();
      const json = await response.json();
      json.parameters = [];
      for (const s of (json.excitation && json.excitation.test_samples) || []) s.design = {};
      await route.fulfill({ response, json });
    };
    await page.route('**/api/model', fixed);
    try {
      await page.goto(url);
      await page.waitForFunction(() => document.body.dataset.state === 'idle'
        && Number(document.body.dataset.predictions || 0) >= 1, null, { timeout: 30_000 })
        .catch(async () => {
          throw new Error(`the page stays ${await page.evaluate(() => document.body.dataset.state)} `
            + `with ${await page.evaluate(() => document.body.dataset.predictions)} predictions`);
        });
      await expectNoError();
      const note = (await page.textContent('#params')).trim();
      check(/no sampled parameters/.test(note), `the design panel says ${JSON.stringify(note)}`);
      check(Object.keys(await plotted()).length > 0, 'no chart drawn');
      check(!(await page.isVisible('#sweep')), 'a sweep is offered without a parameter to sweep');
      const n = await counter('solves');
      await page.click('#solve');
      await waitCounter('solves', n + 1);
      await expectNoError();
      check(solverSeries(await plotted()), 'no solver curve after "Solve exactly"');
      results.noParameters = { note };
    } finally {
      await page.unroute('**/api/model', fixed);
    }
  });

  // ---- 10. the pipeline at a glance: every unit fresh but the study stages' (the test workspace
  // does not run them), Table 4 and the plots shown -------------------------------------------
  await step('pipeline', async () => {
    await page.goto(new URL('/pipeline', url).toString());
    await page.waitForSelector('body[data-polls]', { timeout: TIMEOUT_MS });
    const units = await page.$$eval('tr[data-unit]', (rows) => rows.map((r) => [r.dataset.unit, r.dataset.state]));
    check(units.length > 0, 'the pipeline page lists no unit');
    const study = (unit) => /^study(-[a-z-]+)?\[/.test(unit); // `study[...]`, `study-differences[...]`
    const wrong = units.filter(([unit, state]) => state !== (study(unit) ? 'never run' : 'fresh'));
    check(wrong.length === 0, `units in an unexpected state on the pipeline page: ${JSON.stringify(wrong)}`);
    const table4Rows = await page.$$eval('#table4 tbody tr', (rows) => rows.length);
    check(table4Rows > 0, 'the pipeline page shows no Table 4');
    // Every image finished (loaded or failed) before judging: the page loads its plots lazily
    // (as a user scrolls to them) and a loaded machine may still be fetching them.
    await page.$$eval('img', (imgs) => imgs.forEach((i) => { i.loading = 'eager'; }));
    await page.waitForFunction(() => document.images.length > 0 && [...document.images].every((i) => i.complete),
      null, { timeout: TIMEOUT_MS });
    const plots = await page.$$eval('img', (imgs) => imgs.map((i) => [i.getAttribute('src'), i.complete && i.naturalWidth > 0]));
    check(plots.length > 0 && plots.every(([, ok]) => ok), `evaluate plots not shown: ${JSON.stringify(plots)}`);
    // Table 4 fits its card and its numbers are short (4 significant digits).
    const table4 = await page.evaluate(() => {
      const wrap = document.querySelector('#table4').closest('.table-wrap');
      return {
        fits: wrap.scrollWidth <= wrap.clientWidth + 1,
        numbers: [...document.querySelectorAll('#table4 td.num')].map((c) => c.textContent),
      };
    });
    check(table4.fits, 'Table 4 is wider than its card');
    const long = table4.numbers.filter((t) => t.replace(/^-/, '').replace(/e.*$/, '').replace('.', '').replace(/^0+/, '').length > 4);
    check(table4.numbers.length > 0 && long.length === 0, `Table 4 numbers with more than 4 digits: ${JSON.stringify(long)}`);
    // Headers break only between words (after `_`), never inside one; no cell reads NaN.
    const headers = await page.evaluate(() => [...document.querySelectorAll('#table4 th')].map((th) => {
      const broken = [...th.childNodes].filter((node) => node.nodeType === Node.TEXT_NODE).filter((node) => {
        const range = document.createRange();
        range.selectNodeContents(node);
        return new Set([...range.getClientRects()].map((r) => Math.round(r.top))).size > 1;
      }).map((node) => node.textContent);
      return { text: th.textContent, broken };
    }));
    const brokenHeaders = headers.filter((h) => h.broken.length);
    check(brokenHeaders.length === 0, `Table 4 headers broken inside a word: ${JSON.stringify(brokenHeaders)}`);
    const nanCells = await page.$$eval('#table4 td', (cells) => cells.map((c) => c.textContent).filter((t) => /nan/i.test(t)));
    check(nanCells.length === 0, `Table 4 shows NaN: ${JSON.stringify(nanCells)}`);
    table4.headers = headers.map((h) => h.text);
    results.pipeline = { units, table4_rows: table4Rows, plots: plots.length, table4 };
  });

  // ---- 11. a Sobol study of two parameters started from the sweep view -------------------
  await step('study-start', async () => {
    await page.goto(url);
    await page.waitForSelector('body[data-predictions]', { timeout: TIMEOUT_MS });
    const params = await page.evaluate(() => window.explorerState.summary.parameters.map((p) => p.name));
    await page.locator('#study-start').scrollIntoViewIfNeeded();
    await page.click('#study-start summary');
    await page.selectOption('#sweep-param', params[0]);
    await page.selectOption('#study-kind', 'sensitivity');
    await page.selectOption('#study-param2', params[1]);
    check(await page.isEnabled('#study-from2'), 'the second parameter\'s interval stays disabled');
    await page.fill('#study-n', '16');
    await page.fill('#study-solver-check', '4');
    await page.click('#start-study');
    await page.waitForFunction(() => document.body.dataset.studyState, null, { timeout: 120_000 });
    await expectNoError();
    const state = await page.evaluate(() => document.body.dataset.studyState);
    const status = await page.textContent('#study-status');
    check(state === 'finished', `the study did not finish: ${status}`);
    results.studyStart = {
      name: await page.evaluate(() => document.body.dataset.study),
      design: await page.evaluate(() => window.explorerState.design),
      parameters: [
        { name: params[0], from: Number(await page.inputValue('#sweep-from')), to: Number(await page.inputValue('#sweep-to')) },
        { name: params[1], from: Number(await page.inputValue('#study-from2')), to: Number(await page.inputValue('#study-to2')) },
      ],
      status,
    };
  });

  // ---- 12. the Studies page: the started study's report, table and plots; the pipeline's
  // studies listed with their state ------------------------------------------------------------
  await step('studies', async () => {
    const { name } = results.studyStart;
    await page.click('#study-status a');
    await page.waitForURL(/\/studies#/);
    await page.waitForSelector('body[data-polls]', { timeout: TIMEOUT_MS });
    await expectNoError();
    const listed = await page.$$eval('#study-list tbody tr', (rows) => rows.map((r) => [r.dataset.source, r.dataset.name, r.dataset.state]));
    const card = page.locator(`#study-explorer-${name}`);
    check(await card.count() === 1, `no card for ${name}: ${JSON.stringify(listed)}`);
    const table = await card.locator('.study-table table').evaluate((t) => ({
      file: t.dataset.file,
      header: [...t.tHead.rows[0].cells].map((c) => c.textContent),
      rows: [...t.tBodies[0].rows].map((r) => [...r.cells].map((c) => c.textContent)),
    }));
    const reportTables = await card.locator('.study-report table').count();
    await card.locator('img').evaluateAll((imgs) => imgs.forEach((i) => { i.loading = 'eager'; }));
    await page.waitForFunction((id) => [...document.querySelectorAll(`#${id} img`)].every((i) => i.complete),
      `study-explorer-${name}`, { timeout: TIMEOUT_MS });
    const plots = await card.locator('img').evaluateAll((imgs) => imgs.map((i) => [i.getAttribute('src'), i.naturalWidth]));
    check(plots.length > 0 && plots.every(([, w]) => w > 100), `the study's plots are not shown: ${JSON.stringify(plots)}`);
    check(reportTables > 0, 'the report (summary.md) shows no table');
    const declaration = await card.locator('.study-declaration pre').textContent();
    // Its one-line summary shows the study's name as code, not Markdown backticks.
    const detail = await card.locator('.study-detail').evaluate((p) => ({
      text: p.textContent, code: [...p.querySelectorAll('code')].map((c) => c.textContent),
    }));
    check(!detail.text.includes('`') && detail.code.includes(name),
      `the study's summary shows raw Markdown: ${JSON.stringify(detail)}`);
    results.studies = { listed, table, plots, report_tables: reportTables, declaration, detail };
  });

  // ---- 13. a study of 5000 designs runs beside the page: a slider move redraws at once ----
  await step('study-beside', async () => {
    await page.goto(url);
    await waitCounter('predictions', 1);
    const params = summary.parameters.map((p) => p.name);
    await page.locator('#study-start').scrollIntoViewIfNeeded();
    await page.click('#study-start summary');
    await page.selectOption('#sweep-param', params[0]);
    await page.selectOption('#study-kind', 'monte_carlo');
    await page.selectOption('#study-param2', '');
    await page.fill('#study-n', '5000');
    await page.fill('#study-solver-check', '32');
    const before = await page.evaluate(() => document.body.dataset.study || '');
    await page.click('#start-study');
    await page.waitForFunction((b) => (document.body.dataset.study || '') !== b, before);
    const name = await page.evaluate(() => document.body.dataset.study);
    const running = async () => page.evaluate(async (n) => {
      const list = await (await fetch('/api/studies')).json();
      const s = list.explorer.find((x) => x.name === n);
      return s && s.state === 'running';
    }, name);
    check(await running(), `the study ${name} is not running`);
    const n = await counter('predictions');
    await dragSlider(params[0], 0.4);
    await waitCounter('predictions', n + 1);
    await expectNoError();
    check(await running(), 'the slider move was drawn only after the study ended');
    results.studyBeside = { name, status: await page.textContent('#study-status') };
  });

  // ---- 14. the Studies page: its progress and a Cancel button; cancelled ------------------
  await step('study-cancel', async () => {
    const { name } = results.studyBeside;
    await page.goto(new URL('/studies', url).toString());
    const row = page.locator(`#study-list tbody tr[data-name="${name}"]`);
    await row.locator('progress').waitFor({ timeout: 30_000 });
    const progress = await row.locator('progress').evaluate((p) => ({ value: p.value, max: p.max }));
    check(progress.max >= 5000, `the progress bar counts ${JSON.stringify(progress)}`);
    await page.screenshot({ path: path.join(outDir, `step-${stepNo + 1}-study-progress.png`), fullPage: true });
    await row.locator('button.cancel-study').click();
    await page.waitForSelector(`#study-list tbody tr[data-name="${name}"][data-state="cancelled"]`, { timeout: 60_000 });
    await expectNoError();
    const detail = await page.locator(`#study-list tbody tr[data-name="${name}"] td.detail`).textContent();
    results.studyCancel = { name, progress, detail };
  });

  check(results.consoleErrors.length === 0, `console errors on the page:\n  ${results.consoleErrors.join('\n  ')}`);
}

let code = 0;
try {
  await main();
} catch (e) {
  console.error(`explore.mjs: FAILED: ${e.message}`);
  if (results.consoleErrors.length) console.error(`console errors:\n  ${results.consoleErrors.join('\n  ')}`);
  results.failure = e.message;
  code = 1;
} finally {
  fs.writeFileSync(path.join(outDir, 'results.json'), JSON.stringify(results, null, 1));
  if (context) await context.close().catch(() => {});
  fs.rmSync(profileDir, { recursive: true, force: true });
}
if (code === 0) console.log(`explore.mjs: all steps passed; results in ${path.join(outDir, 'results.json')}`);
process.exit(code);
