"""The viser server inside the API process: one scene and one set of controls per browser tab.

viser has no way to pick content from the URL, so a tab opens on the job the
page asked for last (``focus``, set by POST /api/viewer) or else the newest
done job; its controls then switch job, method and distortion component for
that tab alone (per-client scenes: two tabs never fight over one scene).
"""
from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field
from typing import Any

from ..base.context import Context
from . import data
from .gate import ProxyOnly
from .scene import COMPONENTS, Built, build_scene, set_component

log = logging.getLogger("freecal.viewer")
NONE = "(no finished job yet)"


@dataclass
class Session:
    """One connected tab: its client handle, what it shows, its controls (``gui_*``)."""

    client: Any
    job_id: str | None = None
    component: str = COMPONENTS[0]
    built: Built = field(default_factory=Built)
    labels: dict[str, str] = field(default_factory=dict)   # job dropdown label → job id
    gui: dict[str, Any] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def describe(self) -> dict[str, Any]:
        return {"client_id": self.client.client_id, "job_id": self.job_id, "component": self.component,
                "nodes": self.built.names()}


class Viewer:
    """``Viewer(ctx)`` starts viser on loopback (``port`` 0: any free one); ``stop()`` ends it.

    Browsers reach it through the API's /viewer proxy (``proxy.py``), which checks the token and
    the Origin; viser's own port serves only the proxy (``gate.ProxyOnly``: the key it adds).
    """

    def __init__(self, ctx: Context, host: str = "127.0.0.1", port: int = 0):
        import viser

        self.ctx = ctx
        self.host = host
        self.focus: str | None = None
        self.sessions: dict[int, Session] = {}
        self.server = viser.ViserServer(host=host, port=port, label="freecal 3D view", verbose=False)
        self.gate = ProxyOnly(self.server)   # first: before any callback that sends freecal's data
        self.server.gui.configure_theme(control_layout="floating", control_width="large", show_logo=False)
        # every tab starts behind and above the camera, looking at the boards (scene: y down, 1 = board distance)
        self.server.initial_camera.up = (0.0, -1.0, 0.0)
        self.server.initial_camera.position = (0.9, -0.8, -0.9)
        self.server.initial_camera.look_at = (0.0, 0.3, 0.9)
        self.server.on_client_connect(self._connect)
        self.server.on_client_disconnect(lambda client: self.sessions.pop(client.client_id, None))

    @property
    def port(self) -> int:
        return self.server.get_port()

    @property
    def address(self) -> str:
        """Where the proxy reaches viser: its host, or loopback when it listens on every interface."""
        host = {"0.0.0.0": "127.0.0.1", "": "127.0.0.1", "::": "::1"}.get(self.host, self.host)
        return f"[{host}]:{self.port}" if ":" in host else f"{host}:{self.port}"

    def stop(self) -> None:
        self.server.stop()

    def describe(self) -> list[dict[str, Any]]:
        return [s.describe() for s in list(self.sessions.values())]

    # ---- one tab ---------------------------------------------------------------------
    def _connect(self, client: Any) -> None:
        if not self.gate.admitted(client.client_id):
            return   # not through the proxy: no job list, no scene
        session = Session(client)
        self.sessions[client.client_id] = session
        gui = client.gui
        jobs = self._job_labels(session)
        first = next((label for label, jid in session.labels.items() if jid == self.focus), jobs[0])
        session.gui["gui_job"] = gui.add_dropdown("Job", jobs, initial_value=first)
        session.gui["gui_method"] = gui.add_dropdown("Method", ["—"], initial_value="—")
        session.gui["gui_component"] = gui.add_dropdown("Surfaces", COMPONENTS, initial_value=COMPONENTS[0])
        session.gui["gui_refresh"] = gui.add_button("Reload job list")
        session.gui["gui_legend"] = gui.add_markdown("")
        session.gui["gui_job"].on_update(lambda _: self._show(session, session.labels.get(
            session.gui["gui_job"].value)))
        session.gui["gui_method"].on_update(lambda _: self._pick_method(session))
        session.gui["gui_component"].on_update(lambda _: self._set_component(session))
        session.gui["gui_refresh"].on_click(lambda _: self._refresh(session))
        self._show(session, session.labels.get(first))

    def _job_labels(self, session: Session) -> list[str]:
        session.labels = {}
        for job in data.done_jobs(self.ctx):
            rmse = (job["summary"].get("metrics") or {}).get("rmse")
            label = f"{job['id']} · {job['method']}" + (f" · {rmse:.3f} px" if isinstance(rmse, float) else "")
            session.labels[label] = job["id"]
        return list(session.labels) or [NONE]

    def _refresh(self, session: Session) -> None:
        current = session.gui["gui_job"].value
        session.gui["gui_job"].options = self._job_labels(session)
        if current in session.labels:
            session.gui["gui_job"].value = current

    def _show(self, session: Session, job_id: str | None) -> None:
        with session.lock:
            session.job_id = job_id
            result = data.load(self.ctx, job_id) if job_id else None
            if result is None:
                session.client.scene.reset()
                session.built = Built()
                session.gui["gui_legend"].content = "Finish a calibration job, then press *Reload job list*."
                return
            with session.client.atomic():
                session.built = build_scene(session.client.scene, result, session.component)
            self._methods(session, result)
            session.gui["gui_legend"].content = _legend(result, session.built)

    def _methods(self, session: Session, result: data.JobResult) -> None:
        """The method dropdown lists the methods with a done job on the same set."""
        job = self._job(result.job_id)
        same = [j for j in data.done_jobs(self.ctx) if job is not None and j["set_id"] == job["set_id"]]
        methods = sorted({j["method"] for j in same}) or ["—"]
        session.gui["gui_method"].options = methods
        session.gui["gui_method"].value = job["method"] if job and job["method"] in methods else methods[0]

    def _pick_method(self, session: Session) -> None:
        job = self._job(session.job_id) if session.job_id else None
        method = session.gui["gui_method"].value
        if job is None or job["method"] == method:
            return
        newest = next((j for j in data.done_jobs(self.ctx)
                       if j["set_id"] == job["set_id"] and j["method"] == method), None)
        label = next((lab for lab, jid in session.labels.items() if newest and jid == newest["id"]), None)
        if label is not None:
            session.gui["gui_job"].value = label   # its on_update redraws

    def _set_component(self, session: Session) -> None:
        session.component = session.gui["gui_component"].value
        set_component(session.built, session.component)

    def _job(self, job_id: str) -> dict[str, Any] | None:
        from ..base.repository import jobs

        return jobs.get(self.ctx.db, job_id)


def _legend(result: data.JobResult, built: Built) -> str:
    lg = built.legend
    rmse = result.calibration.metrics.get("rmse")
    return "\n".join([
        f"**{result.method}**, {len(result.boards)} board poses" + (f", rmse {rmse:.3f} px" if rmse else ""),
        f"- corners and vectors: colour = |residual|, 0 to {lg.get('error_max_px', 0):.2f} px (95th percentile);"
        f" vectors ×{lg.get('vector_gain', 0):.0f}",
        f"- surfaces: Δx, Δy (the field's own part over its core, else observed − ideal pinhole pixel: the page's map), blue −{lg.get('field_max_px', 0):.1f} px … red "
        f"+{lg.get('field_max_px', 0):.1f} px (98th percentile; beyond it clipped)",
        "- orange lines: knot grid on the ideal image plane" if "/image_plane/knots" in built.handles
        else "- grey rectangle: the ideal image plane (no knots: not a B-spline method)",
        f"- 1 scene unit = {lg.get('scene_unit', 0):.0f} {result.units} (the median board distance)",
    ])
