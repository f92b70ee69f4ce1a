// Scan: codec and options (exposure, HDR, adaptive projection), a ring plan or adaptive, start;
// progress by stage with the time left from the job's events; cancel; the result when it is done.
import { events, get, post } from "../api.js";
import { act, add, field, fill, fmt, h, notice, select } from "../ui.js";

export async function render(main) {
  const codecs = await get("/v1/codecs");
  const codec = select("codec", codecs.map((c) => [c.name, `${c.name} · ${c.frames} patterns`]), codecs.find((c) => c.default)?.name);
  const label = h("input", { name: "label", maxlength: 200, placeholder: "free text kept with the scan" });
  const keep = h("input", { type: "checkbox", name: "keep_frames" });
  const adaptive = h("input", { type: "checkbox", name: "adaptive" });
  const tolerance = h("input", { type: "number", name: "tolerance_mm", min: 0.001, step: "any", placeholder: "the config's" });
  const exposure = h("input", { name: "exposure", placeholder: "the config's: auto, camera or µs", pattern: "auto|camera|[0-9]+(\\.[0-9]+)?" });
  const hdr = select("hdr", [["", "the config's"], ["auto", "auto (from a pre-capture)"], ...[2, 3, 4, 5].map((n) => [String(n), `${n} exposures`])], "");
  const projection = h("input", { type: "checkbox", name: "adaptive_projection" });
  const plan = h("textarea", { name: "plan", rows: 3, placeholder: "a ring plan (JSON, as slrig plan rings --out writes it); empty: none" });
  const start = h("button", { type: "submit", class: "admin" }, "Start scan");
  const form = h("form", { class: "card" },
    h("div", { class: "row" }, field("Codec", codec), field("Label", label)),
    h("div", { class: "row" }, field("Exposure", exposure, "auto: from a white and a black pre-capture"), field("HDR", hdr, "shiny and dark parts: several exposures, merged"), field("Adaptive projection", projection, "dim the patterns where the camera would clip")),
    h("div", { class: "row" }, field("Keep the raw frames (to reprocess)", keep), field("Adaptive rings (pilot, plan, rings)", adaptive), field("Tolerance (mm)", tolerance)),
    field("Ring plan", plan), h("p", { class: "actions" }, start));
  const progress = h("section", { class: "card", hidden: true });
  add(main, h("h1", {}, "Scan"), form, progress);
  adaptive.addEventListener("change", () => {
    codec.disabled = adaptive.checked; tolerance.disabled = !adaptive.checked;
  });
  tolerance.disabled = true;

  let close = null;
  form.addEventListener("submit", (e) => {
    e.preventDefault();
    act(async () => {
      const ringed = adaptive.checked || plan.value.trim() !== "";  // pilot and rings: the codecs are chosen for it
      const body = { keep_frames: keep.checked, adaptive: adaptive.checked };
      if (!ringed) body.codec = codec.value;
      if (label.value) body.label = label.value;
      if (adaptive.checked && tolerance.value) body.tolerance_mm = Number(tolerance.value);
      const asked = exposure.value.trim();  // a planned scan's pilot and rings both take them
      if (asked) body.exposure = /^[0-9.]+$/.test(asked) ? Number(asked) : asked;
      if (hdr.value) body.hdr = hdr.value === "auto" ? "auto" : Number(hdr.value);
      if (projection.checked) body.adaptive_projection = true;
      if (plan.value.trim()) {
        try { body.plan = JSON.parse(plan.value); } catch { throw new Error("plan: not JSON"); }
      }
      const job = await post("/v1/scans", body);
      if (close) close();
      close = follow(job, progress);
    }, start);
  });
  return () => { if (close) close(); };
}

// Show a job's progress until it ends, then what `done` makes of the finished job; returns the
// function that stops following it.
export function follow(job, box, done = summary) {
  const bar = h("progress", { max: 1, value: 0, "aria-label": "progress" });
  const stage = h("p", { class: "stage" }, "queued");
  const cancel = h("button", { type: "button", class: "admin" }, "Cancel");
  const result = h("div", { class: "result" });
  box.hidden = false;
  fill(box, h("h2", {}, `${job.kind === "calibration" ? "Calibration" : "Scan"} ${job.id}`), bar, stage, h("p", { class: "actions" }, cancel), result);
  box.dataset.state = job.state;
  cancel.addEventListener("click", () => act(() => post(`${job.links.self}/cancel`), cancel));
  return events(job.links.events, {
    progress: (p) => {
      bar.value = p.fraction;
      const left = p.remaining_s === null ? "" : ` · about ${fmt.s(p.remaining_s)} left`;
      stage.textContent = `${p.stage} · ${fmt.pct(p.fraction)} · ${fmt.s(p.elapsed_s)} so far${left}`;
    },
    state: async (s, e) => {
      if (s.state === "queued" || s.state === "running") { stage.textContent = box.dataset.state = s.state; return; }
      e.target.close();
      cancel.hidden = true;
      if (s.state !== "done") { box.dataset.state = s.state; stage.textContent = `${s.state}${s.error ? `: ${s.error}` : ""}`; return; }
      bar.value = 1;
      const finished = await get(job.links.self);
      stage.textContent = "done";
      fill(result, done(finished));
      box.dataset.state = "done";  // once what it made is shown
      notice(`${job.kind === "calibration" ? "Calibration" : "Scan"} ${job.id} is done.`);
    },
  });
}

// "hdr · 0.29, 1.2, 4.7 ms" from a scan's exposure record (each camera's exposures)
function exposed(record) {
  const times = Object.values(record.exposures_us || {})[0] || [];
  return `${record.mode}${times.length ? ` · ${times.map((t) => (t / 1000).toPrecision(2)).join(", ")} ms` : ""}`;
}

export function summary(job) {
  const r = job.result || {};
  const files = r.files || [];
  return h("div", { class: "row" },
    files.includes("preview.png") ? h("img", { src: `${job.links.self}/files/preview.png`, alt: `preview of ${job.id}`, class: "preview" }) : null,
    h("dl", {},
      h("dt", {}, "points"), h("dd", {}, fmt.int(r.points)),
      h("dt", {}, "codec"), h("dd", {}, r.codec || job.request.codec || "–"),
      h("dt", {}, "patterns"), h("dd", {}, fmt.int(r.frames_projected)),
      r.exposure ? [h("dt", {}, "exposure"), h("dd", {}, exposed(r.exposure))] : null,
      h("dt", {}, "rms against the truth"), h("dd", {}, r.metrics ? fmt.mm(r.metrics.rms_mm) : "– (no ground truth)"),
      h("dt", {}, "files"), h("dd", {}, files.map((f) => h("a", { href: `${job.links.self}/files/${f}`, download: f }, f, " "))),
    ),
    h("p", {}, h("a", { href: `#/viewer/${job.id}`, class: "button" }, "Open in the 3D viewer")));
}
