// The 3D viewer: a scan's cloud (or ring mesh) from the daemon's binary stream, decimated to a
// budget first, full resolution on demand; colour modes, point size, and a measured distance
// between two picked points.
import { get } from "../api.js";
import { MODES, Viewer, parseBody } from "../gl.js";
import { add, field, fmt, h, notice, select } from "../ui.js";

export const BUDGET = 300000;

export async function render(main, [id]) {
  if (!id) {
    add(main, h("h1", {}, "3D viewer"), h("p", {}, "Open a scan from ", h("a", { href: "#/scans" }, "Scans"), "."));
    return null;
  }
  const job = await get(`/v1/scans/${id}`);
  add(main, h("h1", {}, `Scan ${id}`));
  const panel = viewerPanel(job);
  add(main, panel.box);
  await panel.load(BUDGET);
  return panel.stop;
}

export function viewerPanel(job) {
  const files = (job.result && job.result.files) || [];
  const canvas = h("canvas", { class: "viewer", width: 960, height: 640, tabindex: 0, "aria-label": `3D view of scan ${job.id}: drag to orbit, shift-drag to pan, wheel or +/- to zoom, arrows to turn` });
  const viewer = new Viewer(canvas);
  const mode = select("mode", Object.keys(MODES), "rgb");
  const errorOption = mode.querySelector('option[value="error"]');
  errorOption.hidden = true;  // until the cloud says it carries its errors (simulated rigs)
  const legend = h("p", { class: "figures legend" }, "");
  const size = h("input", { type: "range", name: "point_size", min: 1, max: 8, step: 0.5, value: 2 });
  const measure = h("input", { type: "checkbox", name: "measure" });
  const full = h("button", { type: "button" }, "Full resolution");
  const mesh = files.includes("mesh.ply") ? h("input", { type: "checkbox", name: "mesh" }) : null;
  const info = h("p", { class: "figures" }, "loading…");
  const reading = h("p", { class: "measure", "aria-live": "polite" }, "");
  const box = h("section", { class: "card" },
    h("div", { class: "row" }, field("Colour", mode), field("Point size", size), field("Measure (click two points)", measure),
      mesh ? field("Ring mesh", mesh) : null, full),
    canvas, info, legend, reading);
  let frame = 0;
  const redraw = () => { cancelAnimationFrame(frame); frame = requestAnimationFrame(() => viewer.draw()); };
  viewer.controls(redraw);
  mode.addEventListener("change", () => { viewer.mode = MODES[mode.value]; redraw(); });
  size.addEventListener("input", () => { viewer.pointSize = Number(size.value); redraw(); });
  let cloud = null;
  const load = async (budget) => {
    const started = performance.now();
    const response = await fetch(`/v1/scans/${job.id}/cloud.bin?budget=${budget}`, { credentials: "same-origin" });
    if (!response.ok) throw new Error(`cloud: HTTP ${response.status}`);
    const buffer = await response.arrayBuffer();
    cloud = parseBody(buffer);
    viewer.load(cloud);
    const h0 = cloud.header;
    info.textContent = `${fmt.int(h0.points)} of ${fmt.int(h0.total)} points · ${(buffer.byteLength / 1e6).toFixed(1)} MB in ${((performance.now() - started) / 1000).toFixed(2)} s`;
    canvas.dataset.points = String(h0.points);
    canvas.dataset.drawn = "1";
    canvas.dataset.drawnAt = String(performance.now());  // since the page's navigation: bench/console.py
    full.hidden = h0.points >= h0.total;
    const hasError = h0.arrays.some((a) => a.name === "error");
    errorOption.hidden = !hasError;
    legend.textContent = hasError ? `error against the truth: 0 mm blue to ${viewer.errorScale.toFixed(3)} mm and more red (twice the 95th percentile)` : "";
  };
  full.addEventListener("click", () => load(0).catch((err) => notice(err.message, "error")));
  if (mesh) mesh.addEventListener("change", async () => {
    if (mesh.checked) {
      const response = await fetch(`/v1/scans/${job.id}/mesh.bin`, { credentials: "same-origin" });
      viewer.load(parseBody(await response.arrayBuffer()));
      viewer.showMesh = true;
    } else { viewer.showMesh = false; viewer.load(cloud); }
    redraw();
  });
  canvas.addEventListener("click", (e) => {
    if (!measure.checked || viewer.moved) return;
    const rect = canvas.getBoundingClientRect();
    const x = (e.clientX - rect.left) * (canvas.width / rect.width), y = (e.clientY - rect.top) * (canvas.height / rect.height);
    const point = viewer.pick(x, y);
    if (!point) { reading.textContent = "no point there; click on the surface"; return; }
    viewer.marks = viewer.marks.length >= 2 ? [point] : [...viewer.marks, point];
    const [a, b] = viewer.marks;
    const show = (p) => `(${p.map((v) => v.toFixed(2)).join(", ")})`;
    reading.textContent = b ? `${show(a)} to ${show(b)}: ${Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]).toFixed(3)} mm` : `first point ${show(a)} mm; click the second`;
  });
  return { box, load: (budget) => load(budget).catch((err) => { info.textContent = err.message; }), stop: () => cancelAnimationFrame(frame), viewer };
}
