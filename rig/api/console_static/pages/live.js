// Live: the live depth stream (each camera's depth, colour-mapped), its rate and latency; start, stop.
import { del, events, get, post } from "../api.js";
import { act, add, field, fmt, h, select } from "../ui.js";

export async function render(main) {
  const codecs = await get("/v1/codecs");
  const status = await get("/v1/live/status");
  const codec = select("codec", codecs.map((c) => [c.name, `${c.name} · ${c.frames} patterns`]), status.codec);
  const start = h("button", { type: "button", class: "admin" }, "Start");
  const stop = h("button", { type: "button", class: "admin" }, "Stop");
  const figures = h("p", { class: "figures" }, "");
  const state = h("span", { class: "state" }, status.state);
  const views = h("div", { class: "cameras" });
  add(main, h("h1", {}, "Live"),
    h("section", { class: "card" }, h("div", { class: "row" }, field("Codec", codec)), h("p", { class: "actions" }, start, stop, " live mode: ", state), figures),
    views);

  let close = null;
  const watch = () => {
    if (close) close();
    close = events("/v1/live?stride=2&colour=true", {
      state: (s) => { state.textContent = s.state; if (s.reason && s.state !== "running") figures.textContent = s.reason; },
      depth: (d) => draw(views, d, figures),
    });
  };
  start.addEventListener("click", () => act(async () => { state.textContent = (await post("/v1/live", { codec: codec.value })).state; watch(); }, start));
  stop.addEventListener("click", () => act(async () => { state.textContent = (await del("/v1/live")).state; }, stop));
  watch();
  return () => { if (close) close(); };
}

function draw(views, d, figures) {
  d.cameras.forEach((camera, i) => {
    let box = views.children[i];
    if (!box) {
      box = h("section", { class: "card camera" }, h("h2", {}, camera.name), h("img", { class: "frame depth", alt: `${camera.name} depth` }), h("p", { class: "range" }));
      add(views, box);
    }
    const img = box.querySelector("img");
    img.src = `data:image/jpeg;base64,${camera.jpeg_base64}`;
    img.dataset.sequence = String(d.sequence);
    box.querySelector(".range").textContent = camera.range_mm ? `near ${camera.range_mm[0].toFixed(1)} mm (red) to far ${camera.range_mm[1].toFixed(1)} mm (blue)` : "no depth";
  });
  const rate = d.sequence_ms > 0 ? 1000 / d.sequence_ms : 0;
  figures.textContent = `sequence ${d.sequence} · ${fmt.int(d.points)} points · ${rate.toFixed(1)} sequences/s · latency ${d.latency_ms.toFixed(0)} ms · ${fmt.int(d.dropped ?? 0)} dropped`;
}
