// Scans: the stored scans with preview, codec, points, accuracy and pattern economy; open,
// compare two, download, delete.
import { del, get } from "../api.js";
import { act, add, fmt, h } from "../ui.js";

const PAGE = 20;

export async function render(main, [offsetText]) {
  const offset = Number(offsetText || 0);
  const page = await get(`/v1/scans?limit=${PAGE}&offset=${offset}`);
  const chosen = new Set();
  const compare = h("a", { class: "button", href: "#/scans", "aria-disabled": "true" }, "Compare the two chosen");
  const update = () => {
    const ids = [...chosen];
    compare.href = ids.length === 2 ? `#/compare/${ids[0]}/${ids[1]}` : "#/scans";
    compare.setAttribute("aria-disabled", String(ids.length !== 2));
  };
  const rows = page.items.map((job) => {
    const r = job.result || {};
    const pick = h("input", { type: "checkbox", "aria-label": `choose ${job.id} to compare`, disabled: job.state !== "done", onchange: (e) => { e.target.checked ? chosen.add(job.id) : chosen.delete(job.id); update(); } });
    const remove = h("button", { type: "button", class: "admin", onclick: (e) => act(async () => { if (confirm(`Delete scan ${job.id}?`)) { await del(job.links.self); row.remove(); } }, e.target) }, "Delete");
    const row = h("tr", {},
      h("td", {}, pick),
      h("td", {}, (r.files || []).includes("preview.png") ? h("img", { class: "thumb", src: `${job.links.self}/files/preview.png`, alt: "", loading: "lazy" }) : ""),
      h("td", {}, job.state === "done" ? h("a", { href: `#/viewer/${job.id}` }, job.id) : job.id, job.request.label ? h("div", { class: "muted" }, job.request.label) : null),
      h("td", {}, h("span", { class: `state ${job.state}` }, job.state)),
      h("td", {}, r.codec || job.request.codec || "–"),
      h("td", { class: "num" }, fmt.int(r.points)),
      h("td", { class: "num" }, r.metrics ? fmt.mm(r.metrics.rms_mm) : "–"),
      h("td", { class: "num" }, r.frames_projected ?? "–"),
      h("td", {}, (r.files || []).includes("cloud.ply") ? h("a", { href: `${job.links.self}/files/cloud.ply`, download: `${job.id}.ply` }, "cloud.ply") : "", " ", remove));
    return row;
  });
  add(main, 
    h("h1", {}, "Scans"),
    h("p", { class: "actions" }, compare, ` ${page.total} scans`),
    h("table", { class: "scans" },
      h("thead", {}, h("tr", {}, ["", "preview", "scan", "state", "codec", "points", "rms (truth)", "patterns", ""].map((c) => h("th", { scope: "col" }, c)))),
      h("tbody", {}, rows)),
    h("p", { class: "actions" },
      offset > 0 ? h("a", { class: "button", href: `#/scans/${Math.max(0, offset - PAGE)}` }, "Newer") : null,
      offset + PAGE < page.total ? h("a", { class: "button", href: `#/scans/${offset + PAGE}` }, "Older") : null));
  return null;
}
