"""Each 3D view tab opens on the job its page showed, over real HTTP and websockets.

A real `freecal serve` (API, worker, viser) with two done calibrations of one
set: a tab whose websocket URL names a job (as the page's "Show in 3D" and "open
in a new tab" do: ``frontend/js/api.js`` ``viewerUrl``) shows that job, whatever
was asked last by POST /api/viewer; its panel names jobs as the page does; the
view selected on the page (``/api/viewer/selection``) is highlighted in the tab
paired with it; a model without a field gets no knot grid; a tab opened on a done
rig job draws the rig (a frustum per camera, the board at every frame).
"""
from __future__ import annotations

import threading
from contextlib import contextmanager

import pytest

from ..conftest import synthetic
from ..core.test_rig import simulated_rig
from .harness import FAST, QUICK, Service, create_job, upload_observations, wait_for, wait_job

pytestmark = pytest.mark.slow
PAIR = "page0pair1key2"


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    pytest.importorskip("viser")
    root = tmp_path_factory.mktemp("viewer-tabs")
    svc = Service(root / "data", root, {**FAST, "FREECAL_VIEWER_PORT": "0"}).start()
    yield svc
    svc.stop()


@pytest.fixture(scope="module")
def jobs(service):
    set_id = upload_observations(service.client, synthetic("radial").train.to_json())
    field = create_job(service.client, set_id, "bspline", QUICK)
    plain = create_job(service.client, set_id, "zhang")
    for job_id in (field, plain):
        assert wait_job(service.client, job_id, 120, service.logs())["state"] == "done"
    return {"set": service.client.get(f"/api/sets/{set_id}").json(), "field": field, "plain": plain}


@contextmanager
def tab(service, **params: str):
    """A websocket to /viewer as viser's page opens it, its frames drained in the background."""
    import viser
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    query = "&".join(f"{k}={v}" for k, v in params.items())
    with connect(f"ws://127.0.0.1:{service.port}/viewer?{query}", subprotocols=[f"viser-v{viser.__version__}"],
                 open_timeout=10, max_size=None) as ws:
        # viser counts a tab connected once it reports its camera, as its page does at once
        ws.send(camera_message())
        def drain() -> None:
            try:
                for _ in ws:
                    pass
            except ConnectionClosed:
                pass

        threading.Thread(target=drain, daemon=True).start()
        yield ws


def camera_message() -> bytes:
    """A ViewerCameraMessage as viser's page sends it (msgpack of its fields and its type)."""
    import msgspec.msgpack
    from viser._messages import ViewerCameraMessage

    message = ViewerCameraMessage(wxyz=(1.0, 0.0, 0.0, 0.0), position=(0.0, 0.0, -1.0), fov=1.0, near=0.01, far=100.0,
                                  image_height=600, image_width=800, look_at=(0.0, 0.0, 0.0), up_direction=(0.0, -1.0, 0.0))
    return msgspec.msgpack.encode(message.as_serializable_dict())


def click_message(client_id: int, node: str) -> bytes:
    """A click on scene node ``node`` of this tab's own scene, as viser's page sends it."""
    import msgspec.msgpack
    from viser._messages import SceneNodeClickMessage

    message = SceneNodeClickMessage(name=node, instance_index=None, ray_origin=(0.0, 0.0, -1.0),
                                    ray_direction=(0.0, 0.0, 1.0), screen_pos=(0.5, 0.5), modifier=None)
    message.owner = str(client_id)   # the tab's own scene, not the shared one
    return msgspec.msgpack.encode(message.as_serializable_dict())


def shown(service, job_id: str) -> dict:
    def check():
        return next((c for c in service.client.get("/api/viewer").json()["clients"]
                     if c["job_id"] == job_id and c["nodes"]), None)

    return wait_for(check, 30, f"a 3D tab drawing job {job_id}", service.logs())


def test_a_tab_opens_on_the_job_its_url_names_not_the_last_asked(service, jobs):
    # the old way (POST /api/viewer) asks for the field job; the tab's URL names the other
    assert service.client.post("/api/viewer", json={"job_id": jobs["field"]}).status_code == 200
    with tab(service, job=jobs["plain"], pair=PAIR):
        client = shown(service, jobs["plain"])
        assert client["job_label"].startswith(jobs["set"]["name"] + " · ")
        assert jobs["plain"] not in client["job_label"]
        assert "/image_plane/knots" not in client["nodes"] and "Knot grid" not in client["layers"]
        assert all(client["layers"].values())
    # a URL without a job (or with a malformed one) falls back to the job asked for last
    with tab(service, job="../etc"):
        assert "/image_plane/knots" in shown(service, jobs["field"])["nodes"]


def test_the_view_selected_is_highlighted_in_3d_and_back(service, jobs):
    with tab(service, job=jobs["field"], pair=PAIR) as ws:
        assert shown(service, jobs["field"])["highlighted"] == []
        # a row of the page's per-view table (view_residuals.json) names the view
        name = service.client.get(f"/api/jobs/{jobs['field']}/view_residuals.json").json()[0]["view"]
        r = service.client.post("/api/viewer/selection", json={"pair": PAIR, "view": name})
        assert r.status_code == 200 and r.json()["view"] == name and r.json()["source"] == "page"

        def highlighted():
            c = shown(service, jobs["field"])
            return c if c["highlighted"] == [name] else None

        assert wait_for(highlighted, 10, "the page's view highlighted in 3D", service.logs())["selected_view"] == name
        got = service.client.get("/api/viewer/selection", params={"pair": PAIR}).json()
        assert got["view"] == name and got["seq"] >= 1

        # a board clicked in 3D: its view is the selection the page polls, and gold in the tab
        ws.send(click_message(shown(service, jobs["field"])["client_id"], "/boards/3/plane"))

        def clicked():
            now = service.client.get("/api/viewer/selection", params={"pair": PAIR}).json()
            return now if now["source"] == "3d" else None

        picked = wait_for(clicked, 10, "the board clicked in 3D to reach the selection", service.logs())
        views = {row["view"] for row in service.client.get(f"/api/jobs/{jobs['field']}/view_residuals.json").json()}
        assert picked["view"] in views and picked["view"] != name and picked["seq"] > got["seq"]
        assert shown(service, jobs["field"])["highlighted"] == [picked["view"]]
    assert service.client.get("/api/viewer/selection", params={"pair": "short"}).status_code == 422


def test_a_tab_opens_on_a_rig_job_and_draws_its_cameras_and_frames(service):
    pair = simulated_rig([range(0, 5), range(0, 5)], seed=2)
    set_ids = [upload_observations(service.client, obs.to_json()) for obs in pair.values()]
    r = service.client.post("/api/jobs", json={"kind": "rig", "set_ids": set_ids, "names": ["left", "right"],
                                               "method": "zhang", "hold_models": True})
    assert r.status_code == 201, r.text
    rig_id = r.json()["id"]
    assert wait_job(service.client, rig_id, 120, service.logs())["state"] == "done"
    assert service.client.post("/api/viewer", json={"job_id": rig_id}).json()["focus"] == rig_id
    with tab(service, job=rig_id):
        client = shown(service, rig_id)
        nodes = set(client["nodes"])
        assert {"/cameras/0/frustum", "/cameras/1/frustum", "/cameras/0/x", "/cameras/1/label"} <= nodes
        assert {f"/boards/{k}/outline" for k in range(5)} <= nodes
        assert not {"/field/dx", "/image_plane/outline", "/residuals/vectors"} & nodes
        assert client["job_label"].startswith("Rig left + right · zhang · ") and client["layers"] == {"Boards": True}
