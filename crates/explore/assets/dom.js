/*
 * The two pages' DOM helpers (served as /assets/dom.js, loaded before app.js and
 * pipeline.js): `pinoDom.$(selector, root)` and `pinoDom.el(tag, attrs, ...children)`.
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

  return { $, el };
})();
