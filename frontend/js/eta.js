// How long a running job still needs, from its own progress history: the samples the poll loop saw
// (progress against time) and the run's average since it started, blended, since a calibration's
// stages do not move at one speed. Shown once there is something to go on.
const WINDOW_S = 30;        // recent samples: the current stage's pace
const MIN_RUN_S = 3;        // before this, or below MIN_PROGRESS %, any estimate is a guess
const MIN_PROGRESS = 3;
const history = new Map();  // key → [{t (s), p (%)}]

/** Record that ``key`` (a job or a set's detection) stands at ``progress`` % now. */
export function observe(key, progress, now = performance.now() / 1000) {
  const h = history.get(key) || [];
  if (!h.length || progress !== h[h.length - 1].p) h.push({ t: now, p: progress });
  while (h.length > 2 && now - h[0].t > WINDOW_S) h.shift();
  history.set(key, h);
}

/** Seconds left for ``key``, or null while there is too little to estimate from.
 * ``runSeconds``: how long it has run (the server's count), when known. */
export function remaining(key, progress, runSeconds, now = performance.now() / 1000) {
  if (!(progress >= MIN_PROGRESS && progress < 99.5)) return null;
  const rates = [];
  if (runSeconds != null && runSeconds >= MIN_RUN_S) rates.push(progress / runSeconds);
  const h = history.get(key) || [];
  if (h.length >= 2) {
    const first = h[0], span = now - first.t;
    if (span >= MIN_RUN_S && progress > first.p) rates.push((progress - first.p) / span);
  }
  if (!rates.length) return null;
  const rate = rates.reduce((a, b) => a + b, 0) / rates.length;
  return rate > 0 ? (100 - progress) / rate : null;
}

/** "about 40 s left", "about 3 min left". */
export function etaText(seconds) {
  if (seconds == null) return "";
  if (seconds < 10) return "a few seconds left";
  if (seconds < 90) return `about ${Math.round(seconds / 5) * 5} s left`;
  return `about ${Math.round(seconds / 60)} min left`;
}

export function forget(key) { history.delete(key); }
