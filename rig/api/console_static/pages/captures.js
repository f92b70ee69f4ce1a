// Calibration from a folder of captures: the operator picks the folder (one sub-folder per board
// pose), the page uploads its images into an imports folder (PUT /v1/imports/{folder}/{path}),
// then asks for the calibration (POST /v1/calibrations with `images`). The bench's own layout
// (view_NN/<camera>.png, view_NN/<projector>_<camera>/NNN.png, as `slrig calibrate --save-views`
// writes it) needs nothing more; another system's captures need their pattern description.
import { post, put } from "../api.js";
import { act, field, h, select } from "../ui.js";

const IMAGE = /\.(png|bmp|tiff?|jpe?g)$/i;
const NAME = /^[A-Za-z0-9][A-Za-z0-9_.-]{0,99}$/;

export function capturesForm(onJob) {
  const folder = h("input", { type: "file", name: "captures", webkitdirectory: true, multiple: true });
  const layout = select("layout", [["bench", "this bench's (view_NN folders)"], ["described", "another system's, with its pattern description"]], "bench");
  const description = h("input", { type: "file", name: "patterns", accept: ".yaml,.yml" });
  const glob = h("input", { type: "text", name: "view_glob", value: "*", size: 12 });
  const source = select("board_image", ["auto", "white", "mean", "modulation"], "auto");
  const board = h("input", { type: "text", name: "board", placeholder: "the config's", size: 24 });
  const model = h("input", { type: "text", name: "model", placeholder: "the config's", size: 16 });
  const what = select("what", [["rig", "rig (cameras and projectors)"], "camera", "projector"], "rig");
  const described = h("div", { class: "row", hidden: true },
    field("Pattern description", description, "YAML, as slrig reconstruct reads it"),
    field("View folders", glob, "which sub-folders are poses (capture_*)"),
    field("Board found in", source));
  const status = h("p", { class: "muted", role: "status" });
  const start = h("button", { type: "submit", class: "admin" }, "Upload and calibrate");
  layout.addEventListener("change", () => { described.hidden = layout.value !== "described"; });
  const form = h("form", { class: "card", "aria-label": "calibrate from captures" },
    h("h2", {}, "From a folder of captures"),
    h("p", { class: "muted" }, "Pick the folder that holds one sub-folder per board pose. Its images are uploaded to the daemon; no device is used."),
    h("div", { class: "row" }, field("Folder", folder), field("Layout", layout), field("What", what)),
    described,
    h("div", { class: "row" }, field("Board", board, "KIND:COLSxROWS:SQUARE_MM, e.g. checker:10x8:75"), field("Lens model", model, "e.g. k1k2 or auto")),
    h("p", { class: "actions" }, start), status);
  form.addEventListener("submit", (e) => {
    e.preventDefault();
    act(async () => {
      const files = captures(folder.files);
      if (!files.length) throw new Error("Pick a folder whose sub-folders hold the images of each pose.");
      const name = `captures-${new Date().toISOString().replace(/[^0-9]/g, "").slice(0, 14)}`;
      const body = { what: what.value, images: name };
      if (board.value.trim()) body.board = board.value.trim();
      if (model.value.trim()) body.model = model.value.trim();
      if (layout.value === "described") {
        if (!description.files.length) throw new Error("Give the captures' pattern description (YAML).");
        files.push(["patterns.yaml", description.files[0]]);
        Object.assign(body, { patterns: "patterns.yaml", view_glob: glob.value.trim() || "*", board_image: source.value });
      }
      for (const [k, [path, file]] of files.entries()) {
        status.textContent = `uploading ${k + 1} of ${files.length}: ${path}`;
        await put(`/v1/imports/${name}/${path}`, file);
      }
      status.textContent = `${files.length} files in imports folder ${name}`;
      onJob(await post("/v1/calibrations", body));
    }, start);
  });
  return form;
}

// [path below the picked folder, file] of every image at most two sub-folders deep.
function captures(list) {
  const out = [];
  for (const file of list) {
    const parts = (file.webkitRelativePath || file.name).split("/").slice(1);  // the picked folder's own name off
    if (parts.length < 2 || parts.length > 3 || !IMAGE.test(file.name) || !parts.every((p) => NAME.test(p))) continue;
    out.push([parts.join("/"), file]);
  }
  return out.sort((a, b) => a[0].localeCompare(b[0]));
}
