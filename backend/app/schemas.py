"""The API's typed bodies (OpenAPI at /docs). Families: XCreate (in), XPublic (out), XsPublic (lists)."""
from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Discriminator, Field, Tag, model_validator

JobState = Literal["queued", "running", "done", "failed", "cancelled"]
SetState = Literal["queued", "detecting", "ready", "failed", "cancelled"]


class Message(BaseModel):
    detail: str = Field(description="what went wrong and what to do")


class Created(BaseModel):
    id: str


class ImagePublic(BaseModel):
    name: str
    status: Literal["pending", "used", "rejected"]
    n_corners: int | None = None
    reason: str | None = None
    sharpness: float | None = None
    width: int | None = None
    height: int | None = None


class Skipped(BaseModel):
    name: str = Field(description="a file of the upload (a zip's member as 'zip: member')")
    reason: str = Field(description="why it was not used, in plain words")


class BoardSuggestion(BaseModel):
    """The board's size as the photos show it, when it is not the size given."""
    spec: str = Field(description="the board spec with that size, e.g. chessboard:15x9:26mm")
    cols: int = Field(description="inner corners across")
    rows: int = Field(description="inner corners down")
    n_photos: int = Field(description="photos in which the whole grid of that size was seen")
    n_images: int = Field(description="photos uploaded")
    message: str = Field(description="what was found and what to do, in plain words")


class SetPublic(BaseModel):
    id: str
    name: str
    source: Literal["images", "observations"]
    board: dict[str, Any] | None
    state: SetState = Field(description="ready once corners are known")
    progress: float = Field(description="detection progress, 0-100 %")
    error: str | None = None
    image_size: list[int] | None = Field(None, description="[width, height] in pixels")
    n_images: int
    n_views: int = Field(description="views with corners")
    coverage: dict[str, Any] | None = None
    warnings: list[str] = []
    created_at: datetime
    detection_job: str | None = None
    images: list[ImagePublic] | None = Field(None, description="per-image detection status (in reads of one set)")
    skipped: list[Skipped] = Field(default_factory=list, description="files of the upload that were not used, "
                                   "and why (in reads of one set)")
    board_suggestion: BoardSuggestion | None = Field(None, description="the board's size as the photos show it, "
                                                     "when detection suggests the size given is wrong")


class DetectionCreate(BaseModel):
    board: str = Field(max_length=200, description="the board to detect in the set's photos, e.g. "
                       "chessboard:15x9:26mm (a set's board_suggestion.spec)")


class SetsPublic(BaseModel):
    sets: list[SetPublic]
    count: int


class JobCreate(BaseModel):
    # the schema says what one_input checks: exactly one of the two inputs, not null
    model_config = {"json_schema_extra": {"oneOf": [
        {"required": ["set_id"], "properties": {"set_id": {"type": "string"}, "observations": {"type": "null"}}},
        {"required": ["observations"], "properties": {"observations": {"type": "object"}, "set_id": {"type": "null"}}},
    ]}}

    kind: Literal["calibrate"] = Field("calibrate", description="a calibration of one camera (the default); "
                                       "\"rig\" for several cameras: RigJobCreate")
    set_id: str | None = Field(None, description="an image set whose corners are ready")
    observations: dict[str, Any] | None = Field(None, description="or corners inline: freecal.observations/1")
    method: str = Field("auto", description="a method name ('auto', the default, chooses the model that best "
                        "predicts views left out of its fit), or 'compare' for all methods")
    settings: dict[str, Any] = Field(default_factory=dict, description="the method's settings, e.g. "
                                     "{\"knots\": \"uniform\", \"intervals\": [8, 8], \"lambda_smooth\": 0.1}")
    exclude: list[str] = Field(default_factory=list, description="names of the set's views to leave out of this "
                               "calibration (curation: re-run without them, no new upload)")

    @model_validator(mode="after")
    def one_input(self) -> JobCreate:
        if (self.set_id is None) == (self.observations is None):
            raise ValueError("give exactly one of set_id (an uploaded image set) or observations "
                             "(a freecal.observations/1 document)")
        return self


class RigJobCreate(BaseModel):
    """Several cameras calibrated together (docs/rigs.md): one ready set per camera, views matched by frame."""
    kind: Literal["rig"] = Field(description="a rig: several cameras fixed together, calibrated together")
    set_ids: list[str] = Field(description="one ready set per camera (two or more, at most the server's "
                               "FREECAL_MAX_RIG_CAMERAS), in the order of the cameras")
    names: list[str] | None = Field(None, description="the cameras' names, one per set, distinct, letters, digits "
                                    "and _ . - (default: the sets' names without their extension, else cam0, cam1, ...)")
    reference: str | None = Field(None, description="the camera the others are placed from (default: the first)")
    method: str = Field("auto", description="each camera's calibration method, as for a calibration ('auto': the "
                        "model that best predicts views left out of its fit); not 'compare'")
    settings: dict[str, Any] = Field(default_factory=dict, description="the method's settings, for every camera")
    hold_models: bool = Field(False, description="keep each camera's model as calibrated alone (OpenCV's "
                              "stereoCalibrate with CALIB_FIX_INTRINSIC); by default the rig's fit refines them")


def _job_kind(body: Any) -> str | None:
    """A job body's kind: "calibrate" when it names none (the API before rigs)."""
    if isinstance(body, dict):
        kind = body.get("kind", "calibrate")
        return kind if isinstance(kind, str) else None
    return getattr(body, "kind", None)


# POST /api/jobs takes either body, told apart by "kind" (absent: a calibration)
JOB_KINDS = ("calibrate", "rig")
AnyJobCreate = Annotated[Annotated[JobCreate, Tag("calibrate")] | Annotated[RigJobCreate, Tag("rig")],
                         Discriminator(_job_kind, custom_error_type="job_kind",
                                       custom_error_message="a job is a JSON object whose \"kind\" is \"calibrate\" (the default) or "
                                                            "\"rig\"")]


class RigSpec(BaseModel):
    """A rig job's cameras, as created (names and reference resolved)."""
    set_ids: list[str] = Field(description="one set per camera, in the order of the cameras")
    names: list[str] = Field(description="the cameras' names")
    reference: str = Field(description="the camera the others are placed from")
    hold_models: bool = Field(description="whether each camera's model was held as calibrated alone")


class Timings(BaseModel):
    queued_seconds: float | None = Field(None, description="from creation to the (first) start")
    run_seconds: float | None = Field(None, description="from the start to the end (or now)")
    stages: dict[str, float] = Field(default_factory=dict, description="seconds per stage of the last run")


class JobPublic(BaseModel):
    id: str
    kind: Literal["detect", "calibrate", "rig"]
    set_id: str | None
    method: str | None
    settings: dict[str, Any]
    exclude: list[str] = Field(default_factory=list, description="the views left out of this calibration")
    rig: RigSpec | None = Field(None, description="a rig job's cameras (kind rig); its summary has each camera's "
                                "rmse, the rig's and the frames used")
    state: JobState
    stage: str | None = Field(description="detect, initialise, knots, control points, joint optimisation, metrics ...")
    progress: float = Field(description="0-100 %")
    error: str | None = Field(description="why it failed, in plain words")
    attempts: int
    cancel_requested: bool
    worker: str | None
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    timings: Timings
    summary: dict[str, Any]
    downloads: dict[str, str] = Field(description="result file name → URL")


class JobsPublic(BaseModel):
    jobs: list[JobPublic]
    count: int


class MethodsPublic(BaseModel):
    methods: list[str]
    compare: bool = Field(description="whether method 'compare' (every method, cross-validated) is available")


class Health(BaseModel):
    status: Literal["ok", "degraded"] = Field(description="degraded: the service answers, but something in "
                                                          "`problems` keeps jobs or writes from working")
    problems: list[str] = Field(default_factory=list, description="what is wrong and what to do, in plain words")
    version: str
    queue: Literal["sqlite", "redis"]
    workers: int = Field(description="workers heard from within the lease time")
    workers_expected: int = Field(description="workers the service should have (FREECAL_WORKERS)")
    storage_writable: bool = Field(True, description="whether the data directory takes writes now "
                                                     "(reads work either way)")
    jobs: dict[str, int] = Field(description="jobs by state")
    queue_available: bool = Field(True, description="whether the queue takes jobs now (Redis reachable)")
    queue_error: str | None = Field(None, description="why not, when it does not")
    max_files: int = Field(500, description="images per set (FREECAL_MAX_FILES): the page holds at most this many "
                                           "camera shots")
    max_upload_bytes: int = Field(1024 * 1024 * 1024, description="bytes per upload (FREECAL_MAX_UPLOAD_BYTES)")
