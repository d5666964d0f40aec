// The only module that talks HTTP: every failure becomes an Error carrying the
// API's own message ({"detail": ...}), which the page shows as is.

export class ApiError extends Error {
  constructor(message, status) { super(message); this.status = status; }
}

async function request(method, path, body) {
  const init = { method, headers: {} };
  if (body instanceof FormData) init.body = body;
  else if (body !== undefined) { init.body = JSON.stringify(body); init.headers["content-type"] = "application/json"; }
  let res;
  try { res = await fetch(path, init); }
  catch (e) { throw new ApiError(`the server cannot be reached (${e.message}): is freecal serve running?`, 0); }
  if (res.status === 204) return null;
  const text = await res.text();
  let data = null;
  try { data = text ? JSON.parse(text) : null; } catch { data = null; }
  if (!res.ok) {
    const detail = data && typeof data.detail === "string" ? data.detail : `${res.status} ${res.statusText}`;
    throw new ApiError(detail, res.status);
  }
  return data;
}

export const api = {
  health: () => request("GET", "/api/health"),
  methods: () => request("GET", "/api/methods"),
  sets: () => request("GET", "/api/sets"),
  set: (id) => request("GET", `/api/sets/${id}`),
  createSet: (form) => request("POST", "/api/sets", form),
  jobs: () => request("GET", "/api/jobs"),
  job: (id) => request("GET", `/api/jobs/${id}`),
  createJob: (body) => request("POST", "/api/jobs", body),
  cancelJob: (id) => request("POST", `/api/jobs/${id}/cancel`),
  file: (id, name) => request("GET", `/api/jobs/${id}/${name}`),
  knotCells: (id) => request("GET", `/api/jobs/${id}/figures/knot-cells`),
  uncertainty: (id) => request("GET", `/api/jobs/${id}/figures/uncertainty`),
  quality: (id) => request("GET", `/api/jobs/${id}/figures/quality`),
  rectifiedUrl: (id, name) => `/api/jobs/${id}/rectified/${encodeURIComponent(name)}`,
  viewer: () => request("GET", "/api/viewer"),
  openViewer: (jobId) => request("POST", "/api/viewer", { job_id: jobId }),
};

export const thumbUrl = (setId, name, size = 160) =>
  `/api/sets/${setId}/images/${encodeURIComponent(name)}/thumbnail?size=${size}`;
