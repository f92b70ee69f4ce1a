// The REST API as the console uses it: the session cookie (HttpOnly, set by POST /v1/session)
// goes with every request; changes carry the session's CSRF token. Nothing else talks to the daemon.

export class ApiError extends Error {
  constructor(status, detail) {
    super(describe(detail) || `HTTP ${status}`);
    this.status = status;
  }
}

function describe(detail) {
  if (typeof detail === "string") return detail;
  if (Array.isArray(detail)) return detail.map((d) => `${(d.loc || []).filter((l) => l !== "body").join(".")}: ${d.msg}`).join("; ");
  return detail ? JSON.stringify(detail) : "";
}

export const session = { role: null, csrf: null };

export async function api(method, path, body) {
  const headers = { Accept: "application/json" };
  if (method !== "GET" && session.csrf) headers["X-CSRF-Token"] = session.csrf;
  const raw = body instanceof Blob;  // a file's bytes, as they are (an upload)
  if (body !== undefined) headers["Content-Type"] = raw ? "application/octet-stream" : "application/json";
  const response = await fetch(path, {
    method, headers, credentials: "same-origin", body: body === undefined || raw ? body : JSON.stringify(body),
  });
  if (response.status === 204) return null;
  const text = await response.text();
  let data = null;
  try { data = text ? JSON.parse(text) : null; } catch { data = text; }
  if (!response.ok) {
    if (response.status === 401) window.dispatchEvent(new Event("slrig-logged-out"));
    throw new ApiError(response.status, data && data.detail !== undefined ? data.detail : data);
  }
  return data;
}

export const get = (path) => api("GET", path);
export const post = (path, body) => api("POST", path, body === undefined ? {} : body);
export const put = (path, body) => api("PUT", path, body);
export const del = (path) => api("DELETE", path);

export async function logIn(key) {
  const view = await api("POST", "/v1/session", { key });
  Object.assign(session, view);
  return view;
}

export async function resume() {
  Object.assign(session, await api("GET", "/v1/session"));
  return session.role !== null;
}

export async function logOut() {
  await api("DELETE", "/v1/session");
  session.role = null;
  session.csrf = null;
}

// Server-sent events of `path`, each `type` to handlers[type]; returns the close function.
export function events(path, handlers) {
  const source = new EventSource(path);
  for (const [type, handler] of Object.entries(handlers)) {
    source.addEventListener(type, (e) => handler(JSON.parse(e.data), e));
  }
  return () => source.close();
}
