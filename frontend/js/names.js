// Names people recognise for sets and jobs: their photos, method or model, and time; never a hex id.

/** "14:05" today, "3 May 14:05" on another day. */
export function when(iso) {
  if (!iso) return "";
  const d = new Date(iso), now = new Date();
  const time = d.toLocaleTimeString([], { hour: "2-digit", minute: "2-digit" });
  return d.toDateString() === now.toDateString() ? time : `${d.toLocaleDateString([], { day: "numeric", month: "short" })} ${time}`;
}

export function setName(set) { return set ? set.name : "inline corners"; }

/** What the job fits: "auto → Kannala-Brandt model (k1..k4)", "compare → zhang", "bspline". */
export function jobWhat(job) {
  const s = job.summary || {};
  if (job.method === "compare") return s.verdict ? `every method compared → ${s.verdict}` : "every method compared";
  if (s.model) return job.method === "auto" ? `auto → ${s.model}` : s.model;
  return `method ${job.method}`;
}

/** "24 images · auto → Kannala-Brandt model (k1..k4) · 14:05". */
export function jobName(job, sets) {
  const set = (sets || []).find((x) => x.id === job.set_id);
  return [setName(set), jobWhat(job), when(job.created_at)].filter(Boolean).join(" · ");
}
