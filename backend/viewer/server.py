"""The viser server inside the API process: one scene and one set of controls per browser tab.

viser's client cannot tell the server its URL, but the proxy passes what the
tab's URL asked for (``gate.Asked``: the job on the page's screen, the page's
pairing key), so a tab opens on the job its page showed; without one, on the
job asked for last by POST /api/viewer (``focus``), else the newest done job.
A rig job is drawn by ``rig_scene.py`` (its cameras and the board at its frames)
in the same tab, from the same job list.
Its controls then switch job, method, layers and distortion component for that
tab alone (per-client scenes: two tabs never fight over one scene), and the
view selected on its page is highlighted (``selection.py``), both ways.
"""
from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field
from typing import Any

from ..base.context import Context
from . import data
from .gate import ProxyOnly
from .layers import LAYERS, highlight, present, set_layers
from .legend import legend
from .names import job_label, rig_label, unique_labels
from .rig_scene import build_rig_scene, rig_legend
from .scene import COMPONENTS, Built, Pose, build_scene, set_component
from .selection import Selected, Selections

log = logging.getLogger("freecal.viewer")
NONE = "(no finished job yet)"


@dataclass
class Session:
    """One connected tab: its client handle, what it shows, its controls (``gui_*``)."""

    client: Any
    pair: str = ""
    job_id: str | None = None
    component: str = COMPONENTS[0]
    layers: dict[str, bool] = field(default_factory=lambda: dict.fromkeys(LAYERS, True))
    selected_view: str | None = None
    built: Built = field(default_factory=Built)
    labels: dict[str, str] = field(default_factory=dict)   # job dropdown label → job id
    gui: dict[str, Any] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def describe(self) -> dict[str, Any]:
        visible = {name: bool(self.built.handles[path].visible) for name, path in LAYERS.items()
                   if path in self.built.handles}
        return {"client_id": self.client.client_id, "job_id": self.job_id, "component": self.component,
                "job_label": next((lab for lab, jid in self.labels.items() if jid == self.job_id), None),
                "nodes": self.built.names(), "layers": visible, "selected_view": self.selected_view,
                "highlighted": [self.built.views[i] for i in range(len(self.built.views))
                                if getattr(self.built.handles.get(f"/boards/{i}/highlight"), "visible", False)]}


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
        self.selections = Selections()
        self.server = viser.ViserServer(host=host, port=port, label="freecal 3D view", verbose=False)
        self.gate = ProxyOnly(self.server)   # first: before any callback that sends freecal's data
        self.server.gui.configure_theme(control_layout="floating", control_width="large", show_logo=False)
        # a tab's first frame, before its camera is aimed at its own scene (``_aim``): behind and above the camera
        default = Built().view
        self.server.initial_camera.up = default.up
        self.server.initial_camera.position = default.position
        self.server.initial_camera.look_at = default.look_at
        self.server.on_client_connect(self._connect)
        self.server.on_client_disconnect(self._disconnect)

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

    def select(self, pair: str, view: str | None) -> Selected:
        """The page paired by ``pair`` selected ``view``: highlight it in that page's tabs."""
        chosen = self.selections.choose(pair, view, "page")
        for session in list(self.sessions.values()):
            if session.pair == pair:
                self._highlight(session, view)
        return chosen

    # ---- one tab ---------------------------------------------------------------------
    def _disconnect(self, client: Any) -> None:
        self.sessions.pop(client.client_id, None)

    def _connect(self, client: Any) -> None:
        if not self.gate.admitted(client.client_id):
            return   # not through the proxy: no job list, no scene
        asked = self.gate.asked(client.client_id)
        session = Session(client, pair=asked.pair)
        self.sessions[client.client_id] = session
        gui = client.gui
        jobs = self._job_labels(session)
        wanted = [asked.job_id, self.focus]
        first = next((lab for want in wanted for lab, jid in session.labels.items() if want and jid == want), jobs[0])
        session.gui["gui_job"] = gui.add_dropdown("Job", jobs, initial_value=first)
        session.gui["gui_method"] = gui.add_dropdown("Method", ["—"], initial_value="—")
        session.gui["gui_component"] = gui.add_dropdown("Surfaces", COMPONENTS, initial_value=COMPONENTS[0])
        with gui.add_folder("Layers"):
            for name in LAYERS:
                box = session.gui[f"gui_layer_{name}"] = gui.add_checkbox(name, initial_value=True)
                box.on_update(lambda _, name=name: self._set_layer(session, name))
        session.gui["gui_overview"] = gui.add_button("Overview (camera and boards)")
        session.gui["gui_refresh"] = gui.add_button("Reload job list")
        session.gui["gui_legend"] = gui.add_markdown("")
        session.gui["gui_job"].on_update(lambda _: self._show(session, session.labels.get(
            session.gui["gui_job"].value)))
        session.gui["gui_method"].on_update(lambda _: self._pick_method(session))
        session.gui["gui_component"].on_update(lambda _: self._set_component(session))
        session.gui["gui_overview"].on_click(lambda _: self._aim(session, session.built.view))
        session.gui["gui_refresh"].on_click(lambda _: self._refresh(session))
        if asked.pair:
            session.selected_view = self.selections.get(asked.pair).view
        self._show(session, session.labels.get(first))

    def _job_labels(self, session: Session) -> list[str]:
        names = data.set_names(self.ctx)
        session.labels = unique_labels([(j["id"], rig_label(j) if j["kind"] == "rig"
                                         else job_label(j, names.get(j["set_id"] or "")))
                                        for j in data.done_jobs(self.ctx)])
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
                session.gui["gui_legend"].content = ("Finish a calibration or rig job, "
                                                     "then press *Reload job list*.")
                return
            rig = isinstance(result, data.RigResult)
            with session.client.atomic():
                session.built = (build_rig_scene(session.client.scene, result) if isinstance(result, data.RigResult)
                                 else build_scene(session.client.scene, result, session.component))
                set_layers(session.built.handles, session.layers)
                highlight(session.built.handles, session.built.views, None if rig else session.selected_view)
            self._on_board_click(session, paired=not rig)
            has = present(session.built.handles)
            # no field, no knots (or a rig: boards alone): the box stays, greyed, and the legend says why
            for name in LAYERS:
                session.gui[f"gui_layer_{name}"].disabled = name not in has
            session.gui["gui_component"].disabled = rig
            self._methods(session, result)
            session.gui["gui_legend"].content = (rig_legend(result, session.built) if isinstance(result, data.RigResult)
                                                 else legend(result, session.built))
        # viser calls a tab connected once it has reported its camera: it can be aimed from the start
        self._aim(session, session.built.view)

    def _on_board_click(self, session: Session, paired: bool = True) -> None:
        """A board clicked in 3D selects its view here and on the paired page (a rig's frame: here only)."""
        for i, view in enumerate(session.built.views):
            sheet = session.built.handles.get(f"/boards/{i}/plane")
            if sheet is not None:
                sheet.on_click(lambda _, view=view: self._clicked(session, view, paired))

    def _clicked(self, session: Session, view: str, paired: bool = True) -> None:
        if session.pair and paired:
            self.selections.choose(session.pair, view, "3d")
            for other in list(self.sessions.values()):
                if other.pair == session.pair:
                    self._highlight(other, view)
        else:
            self._highlight(session, view)

    def _highlight(self, session: Session, view: str | None) -> None:
        session.selected_view = view
        highlight(session.built.handles, session.built.views, view)

    def _aim(self, session: Session, pose: Pose) -> None:
        """Put the tab's camera at ``pose`` (position first: viser moves look_at along with it)."""
        camera = session.client.camera
        camera.up_direction = pose.up
        camera.position = pose.position
        camera.look_at = pose.look_at

    def _methods(self, session: Session, result: data.JobResult | data.RigResult) -> None:
        """The method dropdown lists the methods with a done job on the same set (a rig: its own alone)."""
        job = self._job(result.job_id)
        same = [j for j in data.done_jobs(self.ctx) if job is not None and j["kind"] == job["kind"] == "calibrate"
                and j["set_id"] == job["set_id"]]
        if job is not None and job["kind"] == "rig":
            same = [job]
        methods = sorted({j["method"] for j in same}) or ["—"]
        session.gui["gui_method"].options = methods
        session.gui["gui_method"].value = job["method"] if job and job["method"] in methods else methods[0]

    def _pick_method(self, session: Session) -> None:
        job = self._job(session.job_id) if session.job_id else None
        method = session.gui["gui_method"].value
        if job is None or job["method"] == method or job["kind"] != "calibrate":
            return
        newest = next((j for j in data.done_jobs(self.ctx)
                       if j["kind"] == "calibrate" and j["set_id"] == job["set_id"] and j["method"] == method), None)
        label = next((lab for lab, jid in session.labels.items() if newest and jid == newest["id"]), None)
        if label is not None:
            session.gui["gui_job"].value = label   # its on_update redraws

    def _set_component(self, session: Session) -> None:
        session.component = session.gui["gui_component"].value
        set_component(session.built, session.component)

    def _set_layer(self, session: Session, name: str) -> None:
        session.layers[name] = bool(session.gui[f"gui_layer_{name}"].value)
        set_layers(session.built.handles, {name: session.layers[name]})

    def _job(self, job_id: str) -> dict[str, Any] | None:
        from ..base.repository import jobs

        return jobs.get(self.ctx.db, job_id)
