// The console's shell: log in, then one page at a time by the URL's hash (#/scan, #/viewer/<id>).
import { logIn, logOut, resume, session } from "./api.js";
import { clearNotice, h, notice } from "./ui.js";

const PAGES = {
  rig: () => import("./pages/rig.js"),
  aim: () => import("./pages/aim.js"),
  scan: () => import("./pages/scan.js"),
  live: () => import("./pages/live.js"),
  scans: () => import("./pages/scans.js"),
  viewer: () => import("./pages/viewer.js"),
  compare: () => import("./pages/compare.js"),
  calibration: () => import("./pages/calibration.js"),
  rings: () => import("./pages/rings.js"),
  recognition: () => import("./pages/recognition.js"),
};

const main = document.getElementById("page");
let leave = null;

async function show() {
  if (leave) { leave(); leave = null; }
  clearNotice();
  const [name, ...args] = (location.hash.replace(/^#\/?/, "") || "rig").split("/");
  const load = PAGES[name] || PAGES.rig;
  for (const link of document.querySelectorAll("nav a")) {
    link.toggleAttribute("aria-current", link.getAttribute("href") === `#/${name}`);
  }
  main.replaceChildren(h("p", { class: "muted" }, "Loading…"));
  try {
    const page = await load();
    main.replaceChildren();
    leave = (await page.render(main, args.map(decodeURIComponent))) || null;
    document.title = `slrig · ${main.querySelector("h1")?.textContent || name}`;
  } catch (err) {
    main.replaceChildren(h("p", { class: "notice error" }, err.message));
  }
}

function showLogin(reason) {
  if (leave) { leave(); leave = null; }
  const form = document.getElementById("login-form").content.firstElementChild.cloneNode(true);
  main.replaceChildren(form);
  form.querySelector(".error").textContent = reason || "";
  form.key.focus();
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    const button = form.querySelector("button");
    button.disabled = true;
    try {
      await logIn(form.key.value);
      form.key.value = "";
      loggedIn();
      show();
    } catch (err) {
      form.querySelector(".error").textContent = err.status === 403 ? "That key is not valid." : err.message;
      form.key.select();
    } finally {
      button.disabled = false;
    }
  });
}

function loggedIn() {
  document.getElementById("who").textContent = session.role === "admin" ? "operator" : "read-only";
  document.getElementById("logout").hidden = false;
  document.body.classList.toggle("read-only", session.role !== "admin");
}

document.getElementById("logout").addEventListener("click", async () => {
  try { await logOut(); } catch (err) { notice(err.message, "error"); }
  document.getElementById("who").textContent = "";
  document.getElementById("logout").hidden = true;
  showLogin("Logged out.");
});

window.addEventListener("slrig-logged-out", () => {
  if (session.role) { session.role = null; session.csrf = null; showLogin("The session ended; log in again."); }
});
window.addEventListener("hashchange", () => { if (session.role) show(); });

(async () => {
  try {
    if (await resume()) { loggedIn(); show(); } else showLogin();
  } catch (err) {
    main.replaceChildren(h("p", { class: "notice error" }, `The daemon does not answer: ${err.message}`));
  }
})();
