// Recognition: the gallery, and a scan identified against it: ranked scores with the threshold.
import { get, post } from "../api.js";
import { act, add, field, fill, h, select, table } from "../ui.js";

export async function render(main) {
  const [gallery, scans] = await Promise.all([get("/v1/gallery"), get("/v1/scans?limit=50&state=done")]);
  const entries = gallery.entries;
  const scan = select("scan", scans.items.map((j) => [j.id, `${j.id}${j.request.label ? ` · ${j.request.label}` : ""}`]), scans.items[0]?.id);
  const identify = h("button", { type: "submit", class: "admin" }, "Identify");
  const label = h("input", { name: "label", pattern: "[A-Za-z0-9._-]+", placeholder: "label" });
  const addEntry = h("button", { type: "button", class: "admin" }, "Add to the gallery");
  const result = h("div", {});
  const form = h("form", { class: "card" }, h("div", { class: "row" }, field("Scan", scan), identify, field("Label", label), addEntry), result);
  add(main, h("h1", {}, "Recognition"), form,
    h("section", { class: "card" }, h("h2", {}, `Gallery: ${entries.length} entries`),
      table(["entry", "label", "scan"], entries.map((e) => [e.id ?? "–", e.label ?? "–", e.scan_id ?? "–"]))));
  form.addEventListener("submit", (e) => {
    e.preventDefault();
    act(async () => {
      const answer = await post(`/v1/scans/${scan.value}/identify`, { top: 5 });
      const ranked = answer.matches;
      fill(result, 
        h("p", {}, `Best: `, h("strong", {}, answer.label), ` · threshold ${Number(answer.threshold).toFixed(3)} (${answer.comparison} comparison)`),
        table(["rank", "label", "score", ""], ranked.map((m, i) => [i + 1, m.label, Number(m.score).toFixed(3), m.score >= answer.threshold ? "above the threshold" : "below"])));
    }, identify);
  });
  addEntry.addEventListener("click", () => act(async () => { await post("/v1/gallery", { scan_id: scan.value, label: label.value }); location.reload(); }, addEntry));
  return null;
}
