/*
 * The pages' DOM helpers (an ES module, imported by the explorer's modules, pipeline.js and
 * studies.js): `$(selector, root)`, `el(tag, attrs, ...children)` (text as text nodes, never
 * HTML), `fmt` (format.js) and `poll(path, ms, draw)` for the read-only pages. No inline
 * scripts, no eval.
 */
import { fmt } from './format.js';

export { fmt };

export const $ = (sel, root = document) => root.querySelector(sel);

/** Creates an element: el('td', {class: 'x', dataset: {a: 1}}, 'text', child...). */
export function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v == null || v === false) continue;
    if (k === 'class') node.className = v;
    else if (k === 'dataset') Object.assign(node.dataset, v);
    else if (k in node && typeof v !== 'string') node[k] = v;
    else node.setAttribute(k, v === true ? '' : v);
  }
  for (const c of children) {
    if (c == null || c === false) continue;
    node.append(c instanceof Node ? c : String(c));
  }
  return node;
}

/**
 * Polls GET `path` every `ms` and calls `draw(answer, polls)` (polls: answers drawn before
 * this one); shows a failure in #error, the time in #updated; sets body[data-polls] after
 * each answer drawn and body[data-state] = idle after each try.
 */
export function poll(path, ms, draw) {
  let polls = 0;
  async function once() {
    try {
      const res = await fetch(path, { credentials: 'same-origin' });
      if (!res.ok) {
        let msg = `HTTP ${res.status}`;
        try { const j = await res.json(); if (j && j.error) msg = j.error; } catch (_) { /* not JSON */ }
        throw new Error(msg);
      }
      draw(await res.json(), polls);
      $('#updated').textContent = new Date().toLocaleTimeString();
      $('#error').hidden = true;
      polls += 1;
      document.body.dataset.polls = String(polls);
    } catch (err) {
      $('.error-message').textContent = `GET ${path}: ${err.message || err}`;
      $('#error').hidden = false;
    } finally {
      document.body.dataset.state = 'idle';
      setTimeout(once, ms);
    }
  }
  if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', once);
  else once();
}
