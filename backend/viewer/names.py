"""Job names in the 3D view's panel, worded as the page's job list words them (frontend/js/names.js).

"24 images · auto → Kannala-Brandt model (k1..k4) · 14:05 · 0.262 px": the set,
what was fitted, when, and its rmse; never a hex id. Keep the wording in sync
with ``jobWhat``/``jobName`` there.
"""
from __future__ import annotations

import time
from typing import Any

from ..base.repository.jobs import split_rig


def job_what(job: dict[str, Any]) -> str:
    """What the job fits: "auto → Kannala-Brandt model (k1..k4)", "every method compared → zhang", "bspline"."""
    summary = job.get("summary") or {}
    if job["method"] == "compare":
        return f"every method compared → {summary['verdict']}" if summary.get("verdict") else "every method compared"
    if summary.get("model"):
        return f"auto → {summary['model']}" if job["method"] == "auto" else str(summary["model"])
    return f"method {job['method']}"


def when(ts: float | None, now: float | None = None) -> str:
    """"14:05" today, "3 May 14:05" on another day (the server's local time)."""
    if ts is None:
        return ""
    t, today = time.localtime(ts), time.localtime(time.time() if now is None else now)
    clock = time.strftime("%H:%M", t)
    return clock if t[:3] == today[:3] else f"{t.tm_mday} {time.strftime('%b', t)} {clock}"


def job_label(job: dict[str, Any], set_name: str | None) -> str:
    """The job's name in the panel's Job list, with its rmse when it has one."""
    rmse = ((job.get("summary") or {}).get("metrics") or {}).get("rmse")
    parts = [set_name or "inline corners", job_what(job), when(job.get("created_at"))]
    if isinstance(rmse, (int, float)):
        parts.append(f"{rmse:.3f} px")
    return " · ".join(p for p in parts if p)


def rig_label(job: dict[str, Any]) -> str:
    """A rig job's name in the panel, as the page's Rig card names it (frontend/js/rig.js ``rigName``):
    "Rig left + right · zhang · 14:05 · 0.262 px"."""
    spec = split_rig(job.get("settings") or {})[1] or {}
    rmse = ((job.get("summary") or {}).get("metrics") or {}).get("rmse")
    parts = ["Rig " + " + ".join(spec.get("names") or []), job.get("method") or "", when(job.get("created_at"))]
    if isinstance(rmse, (int, float)):
        parts.append(f"{rmse:.3f} px")
    return " · ".join(p for p in parts if p.strip())


def unique_labels(jobs: list[tuple[str, str]]) -> dict[str, str]:
    """(job id, label) pairs → label → job id; equal labels (two runs in one minute) get " (2)", " (3)"."""
    out: dict[str, str] = {}
    for job_id, label in jobs:
        name, n = label, 1
        while name in out:
            n += 1
            name = f"{label} ({n})"
        out[name] = job_id
    return out
