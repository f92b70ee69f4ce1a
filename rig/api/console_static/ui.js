// Small DOM helpers: elements are built, never parsed from strings, so no data from the daemon
// is ever read as markup.

export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [name, value] of Object.entries(attrs || {})) {
    if (value === undefined || value === null || value === false) continue;
    if (name.startsWith("on")) el.addEventListener(name.slice(2), value);
    else if (name === "class") el.className = value;
    else if (name in el && typeof value !== "string") el[name] = value;
    else el.setAttribute(name, value === true ? "" : value);
  }
  for (const child of children.flat()) {
    if (child === undefined || child === null || child === false) continue;
    el.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return el;
}

// Children as h() takes them (null, undefined and false left out), into `el`: replacing or after.
export function fill(el, ...children) {
  el.replaceChildren(...children.flat().filter((c) => c !== null && c !== undefined && c !== false));
  return el;
}

export function add(el, ...children) {
  el.append(...children.flat().filter((c) => c !== null && c !== undefined && c !== false));
  return el;
}

export function notice(text, kind = "info") {
  const box = document.getElementById("notice");
  box.replaceChildren(h("p", { class: `notice ${kind}` }, text));
  if (kind !== "error") setTimeout(() => { if (box.textContent === text) box.replaceChildren(); }, 4000);
}

export function clearNotice() {
  document.getElementById("notice").replaceChildren();
}

// Run an action, showing its error (and re-enabling what it disabled) instead of losing it.
export async function act(action, button) {
  if (button) button.disabled = true;
  try {
    return await action();
  } catch (err) {
    notice(err.message, "error");
    return undefined;
  } finally {
    if (button) button.disabled = false;
  }
}

export const fmt = {
  int: (n) => (n === null || n === undefined ? "–" : Math.round(n).toLocaleString("en")),
  mm: (v, digits = 3) => (v === null || v === undefined ? "–" : `${Number(v).toFixed(digits)} mm`),
  pct: (v) => (v === null || v === undefined ? "–" : `${(100 * v).toFixed(1)} %`),
  s: (v) => (v === null || v === undefined ? "–" : v < 90 ? `${v.toFixed(1)} s` : `${Math.floor(v / 60)} min ${Math.round(v % 60)} s`),
  when: (iso) => (iso ? new Date(iso).toLocaleString() : "–"),
};

export function table(columns, rows, caption) {
  return h("table", {},
    caption ? h("caption", {}, caption) : null,
    h("thead", {}, h("tr", {}, columns.map((c) => h("th", { scope: "col" }, c)))),
    h("tbody", {}, rows.map((r) => h("tr", {}, r.map((cell) => h("td", {}, cell))))));
}

export function field(label, input, hint) {
  return h("label", { class: "field" }, h("span", {}, label), input, hint ? h("small", {}, hint) : null);
}

export function select(name, options, value) {
  return h("select", { name }, options.map((o) => {
    const [val, text] = Array.isArray(o) ? o : [o, o];
    return h("option", { value: val, selected: String(val) === String(value) }, text);
  }));
}

// Repeat `step` every `ms` until the returned stop function is called (a step's error is shown once).
export function every(ms, step) {
  let stopped = false, timer = null;
  const run = async () => {
    if (stopped) return;
    try { await step(); } catch (err) { notice(err.message, "error"); }
    if (!stopped) timer = setTimeout(run, ms);
  };
  run();
  return () => { stopped = true; clearTimeout(timer); };
}
