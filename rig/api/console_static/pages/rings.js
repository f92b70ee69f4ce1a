// Rings: the ring plan an adaptive scan made (or a stored plan): its rings drawn to scale over the
// projector's image, radii, and what the plan predicts.
import { get } from "../api.js";
import { add, fmt, h, table } from "../ui.js";

export async function render(main, [id]) {
  add(main, h("h1", {}, "Rings"));
  const page = await get("/v1/scans?limit=50&state=done");
  const adaptive = page.items.filter((j) => j.request.adaptive || j.request.plan);
  add(main, h("section", { class: "card" }, h("h2", {}, "Scans with a ring plan"),
    adaptive.length ? h("ul", {}, adaptive.map((j) => h("li", {}, h("a", { href: `#/rings/${j.id}` }, j.id), j.request.label ? ` · ${j.request.label}` : ""))) : h("p", { class: "muted" }, "None yet: start an adaptive scan on the Scan page.")));
  if (!id) return null;
  const manifest = await get(`/v1/scans/${id}/files/manifest.json`);
  const plan = manifest.adaptive && manifest.adaptive.plan ? manifest.adaptive.plan : manifest.plan;
  if (!plan) { add(main, h("p", { class: "notice error" }, `scan ${id} keeps no ring plan`)); return null; }
  const size = (manifest.devices && manifest.devices.projectors && manifest.devices.projectors[0] && manifest.devices.projectors[0].resolution) || [plan.center_px[0] * 2, plan.center_px[1] * 2];
  add(main, h("section", { class: "card" }, h("h2", {}, `Plan of ${id}: ${plan.radii_px.length} rings, tolerance ${fmt.mm(plan.tolerance_mm)}`),
    h("div", { class: "row" }, drawing(plan, size),
      table(["ring", "radius (px)"], plan.radii_px.map((r, i) => [i + 1, r.toFixed(1)]))),
    criteria(plan)));
  return null;
}

function drawing(plan, [width, height]) {
  const ns = "http://www.w3.org/2000/svg";
  const svg = document.createElementNS(ns, "svg");
  svg.setAttribute("viewBox", `0 0 ${width} ${height}`);
  svg.setAttribute("class", "plan");
  svg.setAttribute("role", "img");
  svg.setAttribute("aria-label", `${plan.radii_px.length} rings over the projector image`);
  const frame = document.createElementNS(ns, "rect");
  frame.setAttribute("width", String(width)); frame.setAttribute("height", String(height)); frame.setAttribute("class", "frame");
  svg.append(frame);
  for (const r of plan.radii_px) {
    const c = document.createElementNS(ns, "circle");
    c.setAttribute("cx", String(plan.center_px[0])); c.setAttribute("cy", String(plan.center_px[1])); c.setAttribute("r", String(r));
    svg.append(c);
  }
  return svg;
}

function criteria(plan) {
  const rows = Object.entries(plan.criteria || {}).map(([name, c]) => [name, JSON.stringify(c)]);
  return rows.length ? table(["criterion", "value"], rows, "what the plan was made to meet") : null;
}
