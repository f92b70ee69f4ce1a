// Two scans side by side, each in its own viewer.
import { get } from "../api.js";
import { add, h } from "../ui.js";
import { BUDGET, viewerPanel } from "./viewer.js";

export async function render(main, ids) {
  add(main, h("h1", {}, `Compare ${ids.join(" and ")}`));
  const grid = h("div", { class: "grid" });
  add(main, grid);
  const panels = [];
  for (const id of ids.slice(0, 2)) {
    const panel = viewerPanel(await get(`/v1/scans/${id}`));
    panel.box.prepend(h("h2", {}, id));
    add(grid, panel.box);
    panels.push(panel);
  }
  await Promise.all(panels.map((p) => p.load(BUDGET)));
  return () => panels.forEach((p) => p.stop());
}
