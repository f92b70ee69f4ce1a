// Rig: the devices and their state, health, doctor's checks, projector power, and the job queue
// with cancel.
import { get, post, put } from "../api.js";
import { act, add, every, field, fill, fmt, h, table } from "../ui.js";

export async function render(main) {
  const status = h("section", { class: "card" });
  const devices = h("section", { class: "card" });
  const jobs = h("section", { class: "card" });
  const doctor = h("section", { class: "card" }, h("h2", {}, "Doctor"), h("p", { class: "muted" }, "checking…"));
  const power = h("section", { class: "card", hidden: true });
  add(main, h("h1", {}, "Rig"), h("div", { class: "grid" }, status, devices), h("div", { class: "grid" }, doctor, power), jobs);
  showDoctor(doctor).catch((err) => fill(doctor, h("h2", {}, "Doctor"), h("p", { class: "notice error" }, err.message)));
  const rig = await get("/v1/rig");
  showPower(power, rig.devices.filter((d) => d.kind === "power").map((d) => d.name.replace(/-power$/, "")));

  const refresh = async () => {
    const [health, rig, scans, calibrations] = await Promise.all([
      get("/v1/health"), get("/v1/rig"),
      get("/v1/scans?limit=10"), get("/v1/calibrations?limit=5"),
    ]);
    fill(status, 
      h("h2", {}, rig.name),
      h("p", {}, h("span", { class: `state ${rig.state}` }, rig.state), rig.simulated ? " · simulated bench" : " · hardware"),
      h("p", {}, `daemon ${health.version}: `, h("strong", {}, health.status)),
      health.problems.length ? h("ul", { class: "problems" }, health.problems.map((p) => h("li", {}, p))) : null,
      rig.last_error ? h("p", { class: "notice error" }, `last device fault: ${rig.last_error}`) : null,
      h("p", {}, `queue: ${rig.queue.queued} of ${rig.queue.max}`, rig.running ? ` · running ${rig.running}` : ""),
    );
    fill(devices, h("h2", {}, "Devices"), table(
      ["name", "kind", "driver", "resolution", "open"],
      rig.devices.map((d) => [d.name, d.kind, d.driver, d.resolution ? d.resolution.join(" × ") : "–", d.open ? "yes" : "no"]),
    ));
    const active = [...scans.items, ...calibrations.items].filter((j) => j.state === "queued" || j.state === "running");
    const recent = [...scans.items, ...calibrations.items].sort((a, b) => (a.created < b.created ? 1 : -1)).slice(0, 8);
    fill(jobs, 
      h("h2", {}, "Jobs"),
      active.length ? null : h("p", { class: "muted" }, "Nothing queued or running."),
      table(["job", "kind", "state", "stage", "progress", ""], recent.map((j) => [
        j.id, j.kind, h("span", { class: `state ${j.state}` }, j.state), j.stage || "–", fmt.pct(j.fraction),
        j.state === "queued" || j.state === "running"
          ? h("button", { type: "button", class: "admin", onclick: (e) => act(() => post(`${j.links.self}/cancel`), e.target) }, "Cancel")
          : "",
      ])),
    );
  };
  return every(2000, refresh);
}

// What this machine lacks for the config (slrig doctor, without opening a device).
async function showDoctor(box) {
  const { problems } = await get("/v1/doctor");
  fill(box, h("h2", {}, "Doctor"),
    problems.length
      ? h("ul", { class: "problems" }, problems.map((p) => h("li", {}, h("strong", {}, p.device), `: ${p.problem}`)))
      : h("p", {}, "This machine has what the config needs."));
}

// Power and input of the projectors whose config names a power control (RS-232, PJLink).
function showPower(box, projectors) {
  if (!projectors.length) return;
  box.hidden = false;
  fill(box, h("h2", {}, "Projector power"), projectors.map((name) => {
    const state = h("span", { class: "state" }, "–");
    const input = h("input", { name: `${name}-input`, placeholder: "hdmi, vga; PJLink: 31", size: 12 });
    const show = (view) => { state.textContent = view.state; };
    const call = (method, path, body) => (e) => act(async () => show(await method(`/v1/projectors/${name}/${path}`, body && body())), e.target);
    return h("div", { class: "row power" },
      h("strong", {}, name), state,
      h("button", { type: "button", onclick: call(get, "power") }, "Read state"),
      h("button", { type: "button", class: "admin", onclick: call(put, "power", () => ({ on: true })) }, "On"),
      h("button", { type: "button", class: "admin", onclick: call(put, "power", () => ({ on: false })) }, "Off"),
      field("Input", input),
      h("button", { type: "button", class: "admin", onclick: call(put, "input", () => ({ input: input.value })) }, "Select"));
  }));
}
