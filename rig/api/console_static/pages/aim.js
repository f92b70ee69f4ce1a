// Aim & expose: each camera's live image (saturated red, too dark blue), its histogram and focus
// figure, exposure and gain; the projectors show a setup pattern while aim mode runs.
import { del, get, post, put, session } from "../api.js";
import { act, add, every, field, fill, fmt, h, notice, select } from "../ui.js";

const RENEW_MS = 20000;  // aim mode's time limit is renewed while this page is open
const AIM_SECONDS = 60;  // so a closed browser leaves the projectors dark within a minute

export async function render(main) {
  const [cameras, codecs, rig] = await Promise.all([get("/v1/cameras"), get("/v1/codecs"), get("/v1/rig")]);
  const projectors = rig.devices.filter((d) => d.kind === "projector");
  const controls = patternControls(codecs, projectors);
  const state = h("span", { class: "state" }, "off");
  const start = h("button", { type: "button", class: "admin" }, "Show pattern");
  const stop = h("button", { type: "button", class: "admin" }, "Dark");
  const overlay = h("input", { type: "checkbox", checked: true, name: "overlay" });
  add(main, 
    h("h1", {}, "Aim & expose"),
    h("section", { class: "card" },
      h("h2", {}, "Projector"), controls.form,
      h("p", { class: "actions" }, start, stop, " aim mode: ", state),
      field("Mark clipped pixels (red: saturated, blue: too dark)", overlay)),
    h("div", { class: "cameras" }, cameras.map((c) => cameraView(c, overlay))),
  );

  let renew = null;
  const aim = async () => {
    const view = await post("/v1/aim", { ...controls.value(), seconds: AIM_SECONDS });
    state.textContent = view.state;
    return view;
  };
  start.addEventListener("click", () => act(async () => {
    await aim();
    clearInterval(renew);
    renew = setInterval(() => aim().catch((err) => notice(err.message, "error")), RENEW_MS);
  }, start));
  stop.addEventListener("click", () => act(async () => {
    clearInterval(renew);
    state.textContent = (await del("/v1/aim")).state;
  }, stop));
  controls.form.addEventListener("change", () => { if (renew) act(aim); });
  const poll = every(2000, async () => { state.textContent = (await get("/v1/aim")).state; });
  const views = main.querySelectorAll(".camera");
  for (const view of views) view.start();
  return () => {
    clearInterval(renew);
    poll();
    for (const view of views) view.stop();
    if (renew && session.role === "admin") del("/v1/aim").catch(() => {});
  };
}

function patternControls(codecs, projectors) {
  const pattern = select("pattern", ["white", "black", "checkerboard", "crosshair", "focus", ["codec", "a codec's pattern"]], "crosshair");
  const projector = select("projector", [["", "all"], ...projectors.map((p, i) => [i, p.name])], "");
  const square = h("input", { type: "number", name: "square_px", min: 1, max: 4096, value: 32 });
  const codec = select("codec", codecs.map((c) => [c.name, `${c.name} (${c.frames} patterns)`]), codecs.find((c) => c.default)?.name);
  const index = h("input", { type: "number", name: "index", min: 0, value: 0 });
  const form = h("form", { class: "row", onsubmit: (e) => e.preventDefault() },
    field("Pattern", pattern), field("Projector", projector), field("Square (px)", square),
    field("Codec", codec), field("Pattern k", index));
  const value = () => {
    const body = { pattern: pattern.value, square_px: Number(square.value) };
    if (projector.value !== "") body.projector = Number(projector.value);
    if (pattern.value === "codec") { body.codec = codec.value; body.index = Number(index.value); }
    return body;
  };
  return { form, value };
}

function cameraView(camera, overlay) {
  const canvas = h("canvas", { width: 640, height: Math.round(640 * camera.resolution[1] / camera.resolution[0]), class: "frame", "aria-label": `${camera.name} live image` });
  const histogram = h("canvas", { width: 256, height: 64, class: "histogram", "aria-label": "histogram" });
  const figures = h("p", { class: "figures" }, "No frames yet: show a pattern (aim mode), or start a scan or live mode.");
  const exposure = h("input", { type: "number", name: "exposure_us", min: 1, max: 10000000, step: "any", value: camera.exposure_us });
  const gain = h("input", { type: "number", name: "gain", min: 0, max: 64, step: "any", value: camera.gain ?? "", disabled: camera.has_gain === false });
  const apply = h("button", { type: "submit", class: "admin" }, "Set");
  const form = h("form", { class: "row" }, field("Exposure (µs)", exposure), field("Gain", gain, camera.has_gain === false ? "this driver has no gain control" : null), apply);
  form.addEventListener("submit", (e) => {
    e.preventDefault();
    act(async () => {
      const body = { exposure_us: Number(exposure.value) };
      if (gain.value !== "" && !gain.disabled) body.gain = Number(gain.value);
      const view = await put(`/v1/cameras/${camera.index}/settings`, body);
      notice(`${camera.name}: exposure ${view.exposure_us} µs${view.gain === null ? "" : `, gain ${view.gain}`}`);
    }, apply);
  });
  const box = h("section", { class: "card camera" }, h("h2", {}, camera.name), canvas, h("div", { class: "row" }, histogram, figures), form);
  let running = false, last = 0;
  const times = [];
  box.start = () => {
    running = true;
    (async () => {
      while (running) {
        try {
          const response = await fetch(`/v1/cameras/${camera.index}/frame.jpg?after=${last}&width=640&overlay=${overlay.checked}`, { credentials: "same-origin" });
          if (response.status === 204) {  // no newer frame in time; or nothing captures: look again in a second
            if (response.headers.has("X-Reason")) {
              figures.textContent = "No frames: show a pattern (aim mode), or start a scan or live mode.";
              await new Promise((r) => setTimeout(r, 1000));
            }
            continue;
          }
          if (!response.ok) throw new Error(`camera ${camera.name}: HTTP ${response.status}`);
          last = Number(response.headers.get("X-Frame"));
          const bitmap = await createImageBitmap(await response.blob());
          canvas.getContext("2d").drawImage(bitmap, 0, 0, canvas.width, canvas.height);
          bitmap.close();
          times.push(performance.now());
          if (times.length > 20) times.shift();
          if (response.headers.has("X-Histogram")) drawHistogram(histogram, response.headers.get("X-Histogram"));
          const rate = times.length > 1 ? (1000 * (times.length - 1)) / (times.at(-1) - times[0]) : 0;
          fill(figures, 
            `${rate.toFixed(1)} frames/s · exposure ${response.headers.get("X-Exposure-Us")} µs · gain ${response.headers.get("X-Gain")}`, h("br"),
            `saturated ${fmt.pct(Number(response.headers.get("X-Saturated-Fraction")))} · too dark ${fmt.pct(Number(response.headers.get("X-Dark-Fraction")))}`,
            response.headers.has("X-Sharpness") ? ` · focus ${Number(response.headers.get("X-Sharpness")).toFixed(0)}` : " · a job is running: 5 frames/s, no histogram");
          canvas.dataset.frame = String(last);
          canvas.dataset.exposure = response.headers.get("X-Exposure-Us");
        } catch (err) {
          figures.textContent = err.message;
          await new Promise((r) => setTimeout(r, 1000));
        }
      }
    })();
  };
  box.stop = () => { running = false; };
  return box;
}

function drawHistogram(canvas, header) {
  const counts = (header || "").split(",").map(Number);
  const ctx = canvas.getContext("2d");
  ctx.fillStyle = "#11161c";
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  const peak = Math.max(1, ...counts.map((c) => Math.log1p(c)));
  const w = canvas.width / Math.max(1, counts.length);
  counts.forEach((c, i) => {
    const height = (Math.log1p(c) / peak) * canvas.height;
    ctx.fillStyle = i === counts.length - 1 ? "#e5484d" : i === 0 ? "#3e63dd" : "#c7d0d9";
    ctx.fillRect(i * w, canvas.height - height, Math.max(1, w - 1), height);
  });
}
