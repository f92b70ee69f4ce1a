// Calibration: run one (simulated views on the simulated bench, the rig's board views, or a folder
// of captures the operator uploads), then its report: reprojection error per device and per view,
// the model, the quality warnings and where the board's corners fell.
import { get, post } from "../api.js";
import { act, add, field, fill, fmt, h, select, table } from "../ui.js";
import { capturesForm } from "./captures.js";
import { follow } from "./scan.js";

export async function render(main, [id]) {
  const what = select("what", [["rig", "rig (cameras and projectors)"], "camera", "projector", ["response", "projector response"]], "rig");
  const views = h("input", { type: "number", name: "views", min: 3, max: 40, placeholder: "the config's" });
  const start = h("button", { type: "submit", class: "admin" }, "Calibrate");
  const progress = h("section", { class: "card", hidden: true });
  const form = h("form", { class: "card" }, h("div", { class: "row" }, field("What", what), field("Views", views)), h("p", { class: "actions" }, start));
  const list = h("section", { class: "card" });
  const report = h("section", { class: "card", hidden: true });
  let close = null;
  const watch = (job) => {
    if (close) close();
    close = follow(job, progress, (finished) => { showReport(report, finished); return h("p", {}, "The report is below."); });
  };
  add(main, h("h1", {}, "Calibration"), form, capturesForm(watch), progress, report, list);
  form.addEventListener("submit", (e) => {
    e.preventDefault();
    act(async () => {
      const body = { what: what.value };
      if (views.value) body.views = Number(views.value);
      watch(await post("/v1/calibrations", body));
    }, start);
  });
  const page = await get("/v1/calibrations?limit=20");
  add(list, h("h2", {}, "Calibrations"), h("ul", {}, page.items.map((j) => h("li", {},
    j.state === "done" ? h("a", { href: `#/calibration/${j.id}` }, j.id) : j.id, ` · ${j.request.what} · ${j.state}`,
    j.result && j.result.report ? ` · ${Object.values(j.result.report.devices).map((d) => `${fmt.int(d.views_used.length)} views`).join(", ")}` : ""))));
  if (id) showReport(report, await get(`/v1/calibrations/${id}`));
  return () => { if (close) close(); };
}

function showReport(box, job) {
  const r = job.result || {};
  const devices = (r.report && r.report.devices) || {};
  const files = r.files || [];
  const image = (name, alt) => (files.includes(name) ? h("img", { src: `${job.links.self}/files/${name}`, alt, class: "preview" }) : null);
  box.hidden = false;
  fill(box, h("h2", {}, `Calibration ${job.id}`),
    r.report && r.report.warnings.length ? h("ul", { class: "problems" }, r.report.warnings.map((w) => h("li", {}, w))) : h("p", {}, "The quality gates passed: no warnings."),
    ...Object.entries(devices).map(([name, d]) => h("div", { class: "device" },
      h("h3", {}, `${name} (${d.kind}): rms ${d.rms_px.toFixed(3)} px, lens model ${d.model}`),
      h("p", {}, `${d.views_used.length} views used · coverage ${fmt.pct(d.coverage)}`,
        d.stereo_rms_px === null ? "" : ` · stereo rms ${d.stereo_rms_px.toFixed(3)} px`,
        d.corner_residual_px ? ` · corners: median ${d.corner_residual_px.p50.toFixed(3)}, 95 % ${d.corner_residual_px.p95.toFixed(3)}, largest ${d.corner_residual_px.max.toFixed(3)} px` : ""),
      Object.keys(d.held_out_rms_px || {}).length
        ? h("p", { class: "muted" }, "models compared on views left out: ", Object.entries(d.held_out_rms_px).map(([m, e]) => `${m} ${Number(e).toFixed(4)} px`).join(", "), ` → ${d.model}`)
        : null,
      barChart(d.per_view_rms_px, d.rejected_views, `${name}: reprojection error per view (px)`),
      h("div", { class: "row" },
        h("figure", {}, image(`coverage_${name}.png`, `${name}: where the board's corners fell, every view`), h("figcaption", {}, "corners of every view, and the 8 × 8 cells they cover")),
        h("figure", {}, image(`residuals_${name}.png`, `${name}: each corner's reprojection error, magnified`), h("figcaption", {}, "each corner's error as an arrow, magnified"))),
      views(files.filter((f) => f.startsWith("view_") && f.endsWith(`_${name}.jpg`)), job, name))),
    boardCheck(r.report && r.report.board_check));
}

// Every view as the camera saw it, with the corners found in it.
function views(names, job, device) {
  if (!names.length) return null;
  return h("details", {}, h("summary", {}, `${names.length} views of ${device}, with the corners found`),
    h("div", { class: "views" }, names.map((f) => h("img", { src: `${job.links.self}/files/${f}`, alt: f.replace(".jpg", ""), loading: "lazy", class: "view" }))));
}

// The board as a ruler: its square measured from the calibration, and its flatness, per pair.
function boardCheck(check) {
  if (!check || !Object.keys(check).length) return null;
  return table(["pair", "square (mm)", "error of the square", "worst view", "plane rms (mm)"],
    Object.entries(check).map(([pair, c]) => [pair, c.square, `${c.square_error_pct} %`, `${c.worst_view_square_error_pct} %`, c.plane_rms]),
    "the board as a ruler");
}

// Reprojection error per view as bars (rejected views grey), drawn as SVG.
function barChart(perView, rejected, title) {
  const ns = "http://www.w3.org/2000/svg";
  const entries = Object.entries(perView);
  const peak = Math.max(0.001, ...entries.map(([, v]) => v));
  const svg = document.createElementNS(ns, "svg");
  const width = Math.max(200, entries.length * 24), height = 140;
  svg.setAttribute("viewBox", `0 0 ${width} ${height}`);
  svg.setAttribute("class", "chart");
  svg.setAttribute("role", "img");
  svg.setAttribute("aria-label", title);
  entries.forEach(([view, value], i) => {
    const bar = document.createElementNS(ns, "rect");
    const barHeight = (value / peak) * (height - 30);
    bar.setAttribute("x", String(i * 24 + 4)); bar.setAttribute("width", "18");
    bar.setAttribute("y", String(height - 16 - barHeight)); bar.setAttribute("height", String(barHeight));
    bar.setAttribute("class", view in rejected ? "rejected" : "bar");
    const tip = document.createElementNS(ns, "title");
    tip.textContent = `view ${view}: ${value.toFixed(3)} px${view in rejected ? ` (rejected: ${rejected[view]})` : ""}`;
    bar.append(tip);
    const label = document.createElementNS(ns, "text");
    label.setAttribute("x", String(i * 24 + 13)); label.setAttribute("y", String(height - 3));
    label.textContent = view;
    svg.append(bar, label);
  });
  const top = document.createElementNS(ns, "text");
  top.setAttribute("x", "4"); top.setAttribute("y", "12");
  top.textContent = `max ${peak.toFixed(3)} px`;
  svg.append(top);
  return h("figure", {}, svg, h("figcaption", {}, title));
}
