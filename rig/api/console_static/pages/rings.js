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
  const job = await get(`/v1/scans/${id}`);
  const pilot = (job.result.files || []).includes("pilot_projector.png") ? `/v1/scans/${id}/files/pilot_projector.png` : null;
  const size = (manifest.devices && manifest.devices.projectors && manifest.devices.projectors[0] && manifest.devices.projectors[0].resolution) || [plan.center_px[0] * 2, plan.center_px[1] * 2];
  add(main, h("section", { class: "card plan-card" }, h("h2", {}, `Plan of ${id}: ${plan.radii_px.length} rings, tolerance ${fmt.mm(plan.tolerance_mm)}`),
    h("div", { class: "row" }, h("figure", {}, drawing(plan, size, pilot), h("figcaption", {}, pilot ? `the rings over the pilot scan as the projector saw it (${size[0]} × ${size[1]})` : `the rings on the projector's ${size[0]} × ${size[1]} image`)), profile(plan)),
    h("p", { class: "radii" }, "radii (projector px): ", plan.radii_px.map((r) => r.toFixed(1)).join(", ")),
    errorCurve(plan), criteria(plan)));
  return null;
}

function drawing(plan, [width, height], pilot) {
  const ns = "http://www.w3.org/2000/svg";
  const svg = document.createElementNS(ns, "svg");
  svg.setAttribute("viewBox", `0 0 ${width} ${height}`);
  svg.setAttribute("class", "plan");
  svg.setAttribute("role", "img");
  svg.setAttribute("aria-label", `${plan.radii_px.length} rings over the ${pilot ? "pilot scan as the projector saw it" : "projector image"}`);
  if (pilot) {  // the pilot's surface in projector pixels, where the rings are planned
    const picture = document.createElementNS(ns, "image");
    picture.setAttribute("href", pilot);
    picture.setAttribute("width", String(width)); picture.setAttribute("height", String(height));
    svg.append(picture);
  }
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

// Each way of planning the rings: how many it needs and, where rehearsed on the pilot, the error it
// predicts between the rings (the chosen one marked).
function criteria(plan) {
  const rows = Object.entries(plan.criteria || {}).map(([name, c]) => [
    name.replaceAll("_", " "), c.rings ?? "–", c.rms_mm === undefined ? "–" : `${Number(c.rms_mm).toFixed(4)} mm`,
    c.met === undefined ? "–" : c.met ? "yes" : "no", c.chosen ? "chosen" : "",
  ]);
  return rows.length ? table(["criterion", "rings", "predicted rms", "within tolerance", ""], rows, "rings each criterion needs, and the error it predicts") : null;
}

// The spacing the plan's profile allows at each radius (from the pilot's curvature), with the
// planned rings' own spacing as dots (a rehearsed plan may space them wider where it predicts the
// surface between them within tolerance).
function profile(plan) {
  const ns = "http://www.w3.org/2000/svg";
  const radii = plan.profile.radius_px, allowed = plan.profile.spacing_px;
  if (!radii || !radii.length) return null;
  const rings = plan.radii_px;
  const gaps = rings.slice(1).map((r, i) => [r, r - rings[i]]);
  const xMax = Math.max(...radii, ...rings), yMax = Math.max(...allowed, ...gaps.map((g) => g[1]), 1);
  const W = 480, H = 200, x = (v) => 40 + (v / xMax) * (W - 50), y = (v) => H - 24 - (v / yMax) * (H - 40);
  const svg = document.createElementNS(ns, "svg");
  svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
  svg.setAttribute("class", "chart");
  svg.setAttribute("role", "img");
  svg.setAttribute("aria-label", "allowed ring spacing against radius, and the planned rings' spacing");
  const line = document.createElementNS(ns, "polyline");
  line.setAttribute("points", radii.map((r, i) => `${x(r)},${y(allowed[i])}`).join(" "));
  line.setAttribute("class", "allowed");
  svg.append(line);
  for (const [r, gap] of gaps) {
    const dot = document.createElementNS(ns, "circle");
    dot.setAttribute("cx", String(x(r))); dot.setAttribute("cy", String(y(gap))); dot.setAttribute("r", "3");
    dot.setAttribute("class", "ring");
    svg.append(dot);
  }
  const label = (text, lx, ly) => { const t = document.createElementNS(ns, "text"); t.setAttribute("x", String(lx)); t.setAttribute("y", String(ly)); t.textContent = text; svg.append(t); };
  label(`radius (projector px) to ${Math.round(xMax)}`, W / 2, H - 4);
  label(`spacing to ${Math.round(yMax)} px`, 60, 12);
  return h("figure", {}, svg, h("figcaption", {}, "line: the spacing the profile allows at each radius, from the pilot's curvature; dots: the planned rings' spacing"));
}

// The error each rehearsed criterion predicts against its ring count (every count its search
// tried), with the tolerance as a line: the plan takes the fewest rings under it. A plan judges its
// worst surface region by area (worst_region_mm); plans made before that kept only the rms.
const judged = (p) => p.worst_region_mm ?? p.rms_mm;
function errorCurve(plan) {
  const series = Object.entries(plan.criteria || {}).filter(([, c]) => Array.isArray(c.tried) && c.tried.length);
  if (!series.length) return null;
  const ns = "http://www.w3.org/2000/svg";
  const points = series.flatMap(([, c]) => c.tried);
  const xMax = Math.max(...points.map((p) => p.rings)), yMax = Math.max(plan.tolerance_mm * 1.5, ...points.map(judged));
  const W = 480, H = 200, x = (v) => 40 + (v / xMax) * (W - 50), y = (v) => H - 24 - (Math.min(v, yMax) / yMax) * (H - 40);
  const svg = document.createElementNS(ns, "svg");
  svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
  svg.setAttribute("class", "chart curve");
  svg.setAttribute("role", "img");
  svg.setAttribute("aria-label", "predicted rms error against the number of rings");
  const make = (tag, attrs) => { const e = document.createElementNS(ns, tag); for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, String(v)); svg.append(e); return e; };
  make("line", { x1: 40, x2: W - 10, y1: y(plan.tolerance_mm), y2: y(plan.tolerance_mm), class: "tolerance" });
  series.forEach(([name, c], k) => {
    const tried = [...c.tried].sort((a, b) => a.rings - b.rings);
    make("polyline", { points: tried.map((p) => `${x(p.rings)},${y(judged(p))}`).join(" "), class: `series s${k}` });
    for (const p of tried) {
      const dot = make("circle", { cx: x(p.rings), cy: y(judged(p)), r: 3, class: `series s${k}` });
      const tip = document.createElementNS(ns, "title");
      tip.textContent = `${name.replaceAll("_", " ")}: ${p.rings} rings, worst region ${judged(p).toFixed(4)} mm`;
      dot.append(tip);
    }
    make("text", { x: W - 12, y: 14 + 12 * k, class: `label s${k}` }).textContent = name.replaceAll("_", " ");
  });
  make("text", { x: W / 2, y: H - 4 }).textContent = `rings (to ${xMax})`;
  make("text", { x: 44, y: 12 }).textContent = `rms to ${yMax.toFixed(3)} mm; line: the tolerance`;
  return h("figure", {}, svg, h("figcaption", {}, "predicted rms between the rings against their count, as each search rehearsed it on the pilot"));
}
