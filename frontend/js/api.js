// The only module that talks HTTP: every failure becomes an Error carrying the
// API's own message ({"detail": ...}), which the page shows as is. On a server
// started with FREECAL_TOKEN every request carries the tab's token: fetches in
// the Authorization header, links and <img src> as ?token= (apiUrl, viewerUrl).
import { adoptTokenFromAddress, askForToken, currentToken } from "./token.js";

adoptTokenFromAddress();

export class ApiError extends Error {
  constructor(message, status) { super(message); this.status = status; }
}

async function request(method, path, body) {
  for (;;) {
    const token = currentToken();
    const init = { method, headers: {} };
    if (token) init.headers.authorization = `Bearer ${token}`;
    if (body instanceof FormData) init.body = body;
    else if (body !== undefined) { init.body = JSON.stringify(body); init.headers["content-type"] = "application/json"; }
    let res;
    try { res = await fetch(path, init); }
    catch (e) { throw new ApiError(`the server cannot be reached (${e.message}): is freecal serve running?`, 0); }
    if (res.status === 401) {
      // the server wants a token: ask for it (unless one arrived while this request was on its way), then retry
      if (currentToken() === token) await askForToken(detailOf(await res.text(), res));
      continue;
    }
    if (res.status === 204) return null;
    const text = await res.text();
    if (!res.ok) throw new ApiError(detailOf(text, res), res.status);
    try { return text ? JSON.parse(text) : null; } catch { return null; }
  }
}

function detailOf(text, res) {
  try {
    const data = JSON.parse(text);
    if (data && typeof data.detail === "string") return data.detail;
  } catch { /* not JSON: fall through */ }
  return `${res.status} ${res.statusText}`;
}

/** A URL on this server for a link, an <img src> or an iframe (they cannot send headers): with ?token= when needed. */
export function apiUrl(path, params = {}) {
  const url = new URL(path, window.location.origin);
  for (const [k, v] of Object.entries(params)) url.searchParams.set(k, v);
  const token = currentToken();
  if (token) url.searchParams.set("token", token);
  return url.pathname + url.search;
}

/** The 3D view's page (the API's /viewer proxy). viser's page opens its websocket at its own address
 * without the query, so it is given the whole websocket URL (viser reads ?websocket=) carrying ``params``
 * (the job to open on, the page's pairing key: the proxy passes them on) and the token when needed. */
export function viewerUrl(base, params = {}) {
  const page = new URL(apiUrl(base, params), window.location.origin);
  const ws = new URL(page.pathname.replace(/\/$/, ""), window.location.origin);
  ws.protocol = page.protocol === "https:" ? "wss:" : "ws:";
  for (const [k, v] of Object.entries(params)) ws.searchParams.set(k, v);
  const token = currentToken();
  if (token) ws.searchParams.set("token", token);
  page.searchParams.set("websocket", ws.href);
  return page.pathname + page.search;
}

export const api = {
  health: () => request("GET", "/api/health"),
  methods: () => request("GET", "/api/methods"),
  sets: () => request("GET", "/api/sets"),
  set: (id) => request("GET", `/api/sets/${id}`),
  observations: (id) => request("GET", `/api/sets/${id}/observations.json`),
  createSet: (form) => request("POST", "/api/sets", form),
  detectAgain: (id, board) => request("POST", `/api/sets/${id}/detect`, { board }),
  deleteSet: (id) => request("DELETE", `/api/sets/${id}`),
  jobs: () => request("GET", "/api/jobs"),
  rigJobs: () => request("GET", "/api/jobs?kind=rig"),
  job: (id) => request("GET", `/api/jobs/${id}`),
  createJob: (body) => request("POST", "/api/jobs", body),
  cancelJob: (id) => request("POST", `/api/jobs/${id}/cancel`),
  file: (id, name) => request("GET", `/api/jobs/${id}/${name}`),
  knotCells: (id) => request("GET", `/api/jobs/${id}/figures/knot-cells`),
  uncertainty: (id) => request("GET", `/api/jobs/${id}/figures/uncertainty`),
  quality: (id) => request("GET", `/api/jobs/${id}/figures/quality`),
  diff: (id, other) => request("GET", `/api/jobs/${id}/figures/diff/${other}`),
  rectifiedUrl: (id, name) => apiUrl(`/api/jobs/${id}/rectified/${encodeURIComponent(name)}`),
  mapsUrl: (id) => apiUrl(`/api/jobs/${id}/maps.npz`),
  viewer: () => request("GET", "/api/viewer"),
  viewSelection: (pair) => request("GET", `/api/viewer/selection?pair=${encodeURIComponent(pair)}`),
  selectView: (pair, view) => request("POST", "/api/viewer/selection", { pair, view }),
};

export const thumbUrl = (setId, name, size = 160) =>
  apiUrl(`/api/sets/${setId}/images/${encodeURIComponent(name)}/thumbnail`, { size });
