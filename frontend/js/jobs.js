// The jobs list and the selected job's live progress bar with its current stage.
import { el, px, seconds } from "./format.js";

export function renderJobs(jobs, selectedId, onSelect) {
  const ul = document.getElementById("jobs");
  ul.replaceChildren(...jobs.map((j) => {
    const rmse = j.summary && j.summary.metrics ? j.summary.metrics.rmse : null;
    const what = j.method === "compare" && j.summary.verdict ? `compare → ${j.summary.verdict}` : j.method;
    return el("li", { class: j.id === selectedId ? "selected" : "" },
      el("button", { type: "button", onclick: () => onSelect(j.id), "aria-label": `job ${j.id} ${what}` },
        el("span", { class: "grow" }, `${j.id} · ${what}`),
        el("span", { class: "muted" }, rmse != null ? `rmse ${px(rmse)}` : j.state === "running" ? `${j.progress.toFixed(0)} %` : ""),
        el("span", { class: `state ${j.state}` }, j.state)));
  }));
  if (!jobs.length) ul.append(el("li", { class: "muted" }, el("span", {}, "\u00a0 no calibration jobs yet")));
}

export function renderJob(job, onCancel) {
  document.getElementById("job-detail").hidden = false;
  document.getElementById("job-detail-title").textContent = `Job ${job.id}: ${job.method}`;
  document.getElementById("job-progress").value = job.progress;
  const t = job.timings || {};
  let text = `${job.state}`;
  if (job.state === "running") text += ` · stage: ${job.stage} · ${job.progress.toFixed(0)} % · ${seconds(t.run_seconds)}`;
  else if (job.state === "queued") text += job.stage === "waiting for detection"
    ? " · waiting for the set's corner detection to end (it starts by itself)" : " · waiting for a worker";
  else if (job.state === "done") text += ` · ${seconds(t.run_seconds)}`;
  if (job.error) text += ` · ${job.error}`;
  document.getElementById("job-progress-label").textContent = text;
  const cancel = document.getElementById("job-cancel");
  cancel.hidden = !["queued", "running"].includes(job.state);
  cancel.onclick = () => onCancel(job.id);
}
