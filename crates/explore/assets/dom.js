/*
 * The pages' DOM helpers (served as /assets/dom.js, loaded before app.js, pipeline.js and
 * studies.js): `pinoDom.$(selector, root)`, `pinoDom.el(tag, attrs, ...children)`,
 * `pinoDom.fmt(number, digits)` and `pinoDom.poll(path, ms, draw)` for the read-only pages.
 * Plain ES2020, no inline scripts, no eval.
 */
'use strict';

window.pinoDom = (() => {
  const $ = (sel, root = document) => root.querySelector(sel);

  /** Creates an element: el('td', {class: 'x', dataset: {a: 1}}, 'text', child...). */
  function el(tag, attrs = {}, ...children) {
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

  /** A number for people: 4 significant digits, exponent form when very large or small. */
  function fmt(v, digits = 4) {
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
   * Polls GET `path` every `ms` and calls `draw(answer, polls)` (polls: answers drawn before
   * this one); shows a failure in #error, the time in #updated; sets body[data-polls] after
   * each answer drawn and body[data-state] = idle after each try.
   */
  function poll(path, ms, draw) {
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

  return { $, el, fmt, poll };
})();
