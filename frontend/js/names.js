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

/** Photo names shortened in the middle to about ``max`` characters ("gopro-session-…-L0478.JPG"),
 * as a Map name → shown name: the start and the end (where numbering and extension are) stay,
 * and names that would read the same keep more of their middle until they differ. */
export function shortNames(names, max = 22) {
  const out = new Map(names.map((n) => [n, middleEllipsis(n, max)]));
  for (let keep = max + 4; ; keep += 4) {
    const counts = new Map();
    for (const s of out.values()) counts.set(s, (counts.get(s) || 0) + 1);
    const clashing = names.filter((n) => counts.get(out.get(n)) > 1 && out.get(n) !== n);
    if (!clashing.length) return out;
    for (const n of clashing) out.set(n, middleEllipsis(n, keep));
  }
}

function middleEllipsis(name, max) {
  if (name.length <= max) return name;
  const tail = Math.ceil((max - 1) * 0.6), head = max - 1 - tail;   // the end tells photos of a series apart
  return `${name.slice(0, head)}…${name.slice(name.length - tail)}`;
}
