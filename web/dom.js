// @ts-check
// Small DOM and formatting helpers every view uses: element lookup, SVG elements, number
// formatting, coloured badges, the vehicle colours. No page state.

/** The first element matching `sel` (typed loosely: the page's ids are known to exist).
 * @param {string} sel
 * @param {ParentNode} [root]
 * @returns {any} */
export const $ = (sel, root = document) => root.querySelector(sel);

/** Every element matching `sel`, as an array.
 * @param {string} sel
 * @param {ParentNode} [root]
 * @returns {any[]} */
export const $$ = (sel, root = document) => Array.from(root.querySelectorAll(sel));

const COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
                "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"];

/** The colour of the i-th plan vehicle, the same in every view.
 * @param {number} i
 * @returns {string} */
export const color = (i) => COLORS[i % COLORS.length];

/** The colour of a plan vehicle by id, as `color` gives it by its place in `plan` (dark for
 * ids not in the plan, or with no plan).
 * @param {string} id
 * @param {{vehicles: {id: string}[]} | null} plan
 * @returns {string} */
export const colorOf = (id, plan) => {
  const i = plan ? plan.vehicles.findIndex((v) => v.id === id) : -1;
  return i >= 0 ? color(i) : "#1d232b";
};

/** A number with at most `digits` decimals; "–" for missing values.
 * @param {unknown} x
 * @param {number} [digits]
 * @returns {string} */
export const fmt = (x, digits = 3) => (x === null || x === undefined || Number.isNaN(x)) ? "–"
  : (typeof x === "number" ? Number(x.toFixed(digits)).toString() : String(x));

/** @param {number} x @param {number} lo @param {number} hi @returns {number} */
export const clamp = (x, lo, hi) => Math.min(hi, Math.max(lo, x));

/** A green ("ok") or red ("bad") text span.
 * @param {boolean | undefined} good
 * @param {string} text
 * @returns {HTMLSpanElement} */
export function badge(good, text) {
  const span = document.createElement("span");
  span.className = good ? "ok" : "bad";
  span.textContent = text;
  return span;
}

/** Append to a log list and keep the list (not the page) scrolled to its end.
 * @param {HTMLElement} list
 * @param {HTMLElement} item */
export function appendScrolled(list, item) {
  list.appendChild(item);
  list.scrollTop = list.scrollHeight;
}

/** An SVG element with attributes, appended to `parent` when given.
 * @param {string} tag
 * @param {Record<string, string | number>} attrs
 * @param {Element} [parent]
 * @returns {SVGElement} */
export function svgEl(tag, attrs, parent) {
  const el = /** @type {SVGElement} */ (document.createElementNS("http://www.w3.org/2000/svg", tag));
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, String(v));
  if (parent) parent.appendChild(el);
  return el;
}
