// The capture card: board photos taken live from a webcam or a USB camera. Each photo is the video track's
// frame at its full resolution, kept as PNG (lossless: no JPEG blur on the corners), and the shots go up as a
// new set through the page's one upload path (upload.js's uploadRequest, then main.js's submit).
import { api } from "./api.js";
import { uploadRequest } from "./upload.js";
import { CAMERA, cameraProblem } from "./words.js";

const $ = (id) => document.getElementById(id);
const MB = 1024 * 1024;
// the most a camera is asked for: getUserMedia then picks the device's largest format
const LARGEST = { width: { ideal: 8192 }, height: { ideal: 8192 } };

const state = {
  stream: null,
  shots: [],        // {file: File, url: object URL of the thumbnail}
  counter: 0,       // shot names keep their number when others are removed: shot01.png, shot02.png, …
  limits: { max_files: 500, max_upload_bytes: 1024 * MB },   // the service's defaults until /api/health says
  sending: false,
};

function say(text) { $("capture-status").textContent = text; }

function problem(text) {
  const box = $("capture-message");
  box.textContent = text || "";
  box.hidden = !text;
}

function buttons() {
  const on = !!state.stream;
  $("capture-start").disabled = on;
  $("capture-stop").disabled = !on;
  $("capture-take").disabled = !on;
  $("capture-use").disabled = !state.shots.length || state.sending;
}

const bytes = () => state.shots.reduce((s, x) => s + x.file.size, 0);

function renderShots() {
  const list = $("capture-shots");
  list.replaceChildren(...state.shots.map((shot) => {
    const li = document.createElement("li");
    const img = document.createElement("img");
    img.src = shot.url;
    img.alt = `photo ${shot.file.name}`;
    const name = document.createElement("span");
    name.className = "name";
    name.textContent = shot.file.name;
    const remove = document.createElement("button");
    remove.type = "button";
    remove.textContent = "Remove";
    remove.setAttribute("aria-label", `Remove ${shot.file.name}`);
    remove.addEventListener("click", () => removeShot(shot));
    li.append(img, name, remove);
    return li;
  }));
  const n = state.shots.length;
  $("capture-count").textContent = n
    ? `${n} photo(s) taken, ${(bytes() / MB).toFixed(1)} MB (at most ${state.limits.max_files} per set)` +
      (n < 10 ? `: take ${10 - n} more or so for a good set` : "")
    : `no photos taken yet (at most ${state.limits.max_files} per set)`;
  buttons();
}

function removeShot(shot) {
  const i = state.shots.indexOf(shot);
  if (i < 0) return;
  URL.revokeObjectURL(shot.url);
  state.shots.splice(i, 1);
  problem("");
  renderShots();
  say(`${shot.file.name} removed: ${state.shots.length} photo(s) left.`);
  // keyboard users stay in the strip: the next Remove button, else the previous, else Take photo
  const next = $("capture-shots").querySelectorAll("button")[Math.min(i, state.shots.length - 1)];
  (next || (state.stream ? $("capture-take") : $("capture-start"))).focus();
}

function clearShots() {
  for (const shot of state.shots) URL.revokeObjectURL(shot.url);
  state.shots = [];
  state.counter = 0;
  renderShots();
}

async function pickerFor(track) {
  // labels are readable once the camera is allowed: list the cameras when there is a choice
  const select = $("capture-device");
  let cameras = [];
  try { cameras = (await navigator.mediaDevices.enumerateDevices()).filter((d) => d.kind === "videoinput"); }
  catch { /* no list: no picker */ }
  const current = track.getSettings().deviceId;
  select.replaceChildren(...cameras.map((d, k) => {
    const o = document.createElement("option");
    o.value = d.deviceId;
    o.textContent = d.label || `camera ${k + 1}`;
    o.selected = d.deviceId === current;
    return o;
  }));
  const several = cameras.length > 1;
  select.hidden = !several;
  $("capture-device-label").hidden = !several;
}

async function largest(track) {
  // some browsers start at 640×480 whatever was asked: ask again for the largest size the camera reports
  const caps = track.getCapabilities ? track.getCapabilities() : {};
  const now = track.getSettings();
  if (caps.width && caps.height && caps.width.max > (now.width || 0)) {
    try { await track.applyConstraints({ width: { ideal: caps.width.max }, height: { ideal: caps.height.max } }); }
    catch { /* keep the size it has */ }
  }
}

async function start(deviceId) {
  problem("");
  if (!window.isSecureContext) { problem(CAMERA.insecure(location.origin, location.port || "8000")); return; }
  if (!navigator.mediaDevices || !navigator.mediaDevices.getUserMedia) { problem(CAMERA.unsupported); return; }
  stop(false);
  say("Asking for the camera…");
  $("capture-start").disabled = true;
  let stream;
  try {
    const video = { ...LARGEST, ...(deviceId ? { deviceId: { exact: deviceId } } : {}) };
    stream = await navigator.mediaDevices.getUserMedia({ video, audio: false });
  } catch (e) {
    problem(cameraProblem(e));
    say("Camera off.");
    buttons();
    return;
  }
  state.stream = stream;
  const track = stream.getVideoTracks()[0];
  await largest(track);
  track.addEventListener("ended", () => { if (state.stream === stream) { stop(false); problem(CAMERA.ended); } });
  const preview = $("capture-video");
  preview.srcObject = stream;
  preview.hidden = false;
  await new Promise((resolve) => {
    if (preview.readyState >= 1 && preview.videoWidth) resolve();
    else preview.addEventListener("loadedmetadata", resolve, { once: true });
  });
  try { await preview.play(); } catch { /* muted previews play; a refusal leaves the first frame */ }
  await pickerFor(track);
  buttons();
  say(`Camera on: ${preview.videoWidth}×${preview.videoHeight} px` + (track.label ? ` (${track.label})` : "") +
      ". Take photo, or the space bar on the preview, keeps the frame at this full size.");
}

function stop(announce = true) {
  if (state.stream) for (const t of state.stream.getTracks()) t.stop();
  state.stream = null;
  const preview = $("capture-video");
  preview.srcObject = null;
  preview.hidden = true;
  buttons();
  if (announce) say("Camera off. The photos taken are kept.");
}

async function take() {
  const video = $("capture-video");
  if (!state.stream || !video.videoWidth) return;
  if (state.shots.length >= state.limits.max_files) { problem(CAMERA.full(state.limits.max_files)); return; }
  // the frame as the track delivers it (videoWidth × videoHeight), not as the preview shows it
  const canvas = document.createElement("canvas");
  canvas.width = video.videoWidth;
  canvas.height = video.videoHeight;
  canvas.getContext("2d").drawImage(video, 0, 0, canvas.width, canvas.height);
  const blob = await new Promise((resolve) => canvas.toBlob(resolve, "image/png"));
  if (!blob) { problem(CAMERA.other("the frame could not be read")); return; }
  if (bytes() + blob.size > state.limits.max_upload_bytes) {
    problem(CAMERA.heavy((state.limits.max_upload_bytes / MB).toFixed(0)));
    return;
  }
  state.counter += 1;
  const name = `shot${String(state.counter).padStart(2, "0")}.png`;
  const file = new File([blob], name, { type: "image/png" });
  state.shots.push({ file, url: URL.createObjectURL(blob) });
  problem("");
  renderShots();
  say(`${name} taken (${canvas.width}×${canvas.height} px): ${state.shots.length} photo(s).`);
  if (state.shots.length >= state.limits.max_files) problem(CAMERA.full(state.limits.max_files));
}

async function use(onSubmit) {
  if (!state.shots.length || state.sending) return;
  state.sending = true;
  buttons();
  const n = state.shots.length;
  say(`Sending ${n} photo(s)…`);
  try {
    const sent = await onSubmit(uploadRequest(state.shots.map((s) => s.file)));
    if (sent) {
      clearShots();
      say(`${n} photo(s) sent as a new set: its detection and calibration are under Sets and jobs.`);
    } else say(`The ${n} photo(s) were not sent (the message at the top says why): they are kept.`);
  } finally {
    state.sending = false;
    buttons();
  }
}

/** Wire the capture card; ``onSubmit({form, method, settings})`` is the upload's own (main.js). */
export function initCapture(onSubmit) {
  $("capture-start").addEventListener("click", () => start());
  $("capture-stop").addEventListener("click", () => stop());
  $("capture-take").addEventListener("click", take);
  $("capture-use").addEventListener("click", () => use(onSubmit));
  $("capture-device").addEventListener("change", (e) => start(e.target.value));
  $("capture-video").addEventListener("keydown", (e) => {
    if (e.key === " " || e.code === "Space") { e.preventDefault(); take(); }
  });
  window.addEventListener("pagehide", () => stop(false));   // let the camera's light go off
  renderShots();
  api.health().then((h) => {
    for (const k of ["max_files", "max_upload_bytes"]) if (Number.isFinite(h[k]) && h[k] > 0) state.limits[k] = h[k];
    renderShots();
  }).catch(() => { /* the defaults stand; the health line says the service is unreachable */ });
}
