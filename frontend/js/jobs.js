// The jobs list and the selected job's live progress bar with its current stage.
import { etaText, observe, remaining } from "./eta.js";
import { el, px, seconds } from "./format.js";
import { jobName, jobWhat, setName } from "./names.js";

export function renderJobs(jobs, selectedId, onSelect, sets = []) {
  const ul = document.getElementById("jobs");
  ul.replaceChildren(...jobs.map((j) => {
    const rmse = j.summary && j.summary.metrics ? j.summary.metrics.rmse : null;
    const name = jobName(j, sets);
    return el("li", { class: j.id === selectedId ? "selected" : "" },
      el("button", { type: "button", onclick: () => onSelect(j.id), "aria-label": `job: ${name}`, "data-job": j.id, title: name },
        el("span", { class: "grow" }, name),
        el("span", { class: "muted" }, rmse != null ? `rmse ${px(rmse)}` : j.state === "running" ? `${j.progress.toFixed(0)} %` : ""),
        el("span", { class: `state ${j.state}` }, j.state)));
  }));
  if (!jobs.length) ul.append(el("li", { class: "muted" }, el("span", {}, "\u00a0 no calibration jobs yet")));
}

/** No calibration shown (the one shown was deleted). */
export function hideJob() { document.getElementById("job-detail").hidden = true; }

export function renderJob(job, onCancel, sets = []) {
  document.getElementById("job-detail").hidden = false;
  const set = sets.find((x) => x.id === job.set_id);
  document.getElementById("job-detail-title").textContent = `Calibration of ${setName(set)}: ${jobWhat(job)}`;
  document.getElementById("job-progress").value = job.progress;
  const t = job.timings || {};
  let text = `${job.state}`;
  if (job.state === "running") {
    observe(job.id, job.progress);
    const eta = etaText(remaining(job.id, job.progress, t.run_seconds));
    text += ` · stage: ${job.stage} · ${job.progress.toFixed(0)} % · ${seconds(t.run_seconds)}` + (eta ? ` · ${eta}` : "");
  }
  else if (job.state === "queued") text += job.stage === "waiting for detection"
    ? " · waiting for the set's corner detection to end (it starts by itself)" : " · waiting for a worker";
  else if (job.state === "done") text += ` · ${seconds(t.run_seconds)}`;
  if (job.error) text += ` · ${job.error}`;
  const active = ["queued", "running"].includes(job.state);
  if (!active) cancelling.delete(job.id);
  // a cancel takes a second or two to reach a running job: say at once that it was asked for
  if (cancelling.has(job.id)) text = `cancelling (asked for) · ${text}`;
  document.getElementById("job-progress-label").textContent = text;
  const cancel = document.getElementById("job-cancel");
  cancel.hidden = !active;
  cancel.disabled = cancelling.has(job.id);
  cancel.onclick = () => {
    cancelling.add(job.id);
    cancel.disabled = true;
    document.getElementById("job-progress-label").textContent = `cancelling (asked for) · ${text}`;
    onCancel(job.id);
  };
}

const cancelling = new Set();   // jobs whose cancel was asked for here and that have not ended yet
