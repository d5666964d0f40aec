// The API speaks to programs ("invalid request: files: Field required (see /docs for the schema)");
// the page speaks to people. Messages that name a request field are said again in page words.
export const NO_FILES = "Choose the photos first: drop images, a .zip or an observations .json on the box above " +
  "(no files chosen).";
export const deleteSetQuestion = (name) => `Delete the set "${name}", its photos and its calibrations from the ` +
  "server? This cannot be undone.";
// what was shown is gone: deleted in another tab or through the API while this page showed it
export const SET_GONE = "The set shown here was deleted (in another tab, or through the API): pick another set, " +
  "or upload photos.";
export const JOB_GONE = "The calibration shown here was deleted (with its set, in another tab or through the API): " +
  "pick another calibration.";

// request fields → what the page calls them
const FIELDS = {
  files: "the photos", board: "the board", name: "the set name", method: "the method", settings: "the settings",
  set_id: "the image set", observations: "the corners file",
  set_ids: "the cameras' sets", names: "the camera names", reference: "the reference camera",
};

// a rig's refusals name the request field first ("names: 'a' is given to more than one camera; …")
const LEADING_FIELD = /^(set_ids|names|reference): (.*)$/s;
const SET_ID = / \([0-9a-f]{8,}\)/g;   // "set 'left.json' (9f2c…) is detecting": the page names sets, never by id

const capitalise = (s) => s.charAt(0).toUpperCase() + s.slice(1);

function sayPart(part) {
  const [where, ...rest] = part.split(": ");
  const what = rest.join(": ");
  if (!what) return capitalise(where.replace(/^value error, /i, "")) + ".";
  const field = FIELDS[where.split(".")[0]] || `the ${where.replace(/\./g, " ")}`;
  if (/field required/i.test(what)) return where === "files" ? NO_FILES : `${capitalise(field)} is missing.`;
  return `${capitalise(field)}: ${what.replace(/^value error, /i, "").replace(/^./, (c) => c.toLowerCase())}.`;
}

/** ``message`` in page words: schema-speak rewritten, anything else as the API said it. */
export function pageWords(message) {
  const m = /^invalid request: (.*?)(?: \(see \/docs for the schema\))?$/s.exec(message || "");
  if (m) return m[1].split("; ").map(sayPart).join(" ");
  const f = LEADING_FIELD.exec(message || "");
  return f ? `${capitalise(FIELDS[f[1]])}: ${f[2].replace(SET_ID, "")}` : message;
}

// The capture card's camera problems (capture.js), by the DOMException's name getUserMedia rejects with:
// what happened and what to do, uploading photos always being the way around.
const OR_UPLOAD = "or upload photos instead (the box above).";
export const CAMERA = {
  insecure: (origin, port) => `The browser lets only secure pages use a camera, and ${origin} is not one: open ` +
    `the page as http://localhost:${port}/ on the computer that runs freecal, or over https; ${OR_UPLOAD}`,
  unsupported: `This browser cannot give a page a camera: try a recent Chrome, Edge, Firefox or Safari; ${OR_UPLOAD}`,
  refused: "The camera was refused: allow it for this page (the camera icon in the address bar, or the " +
    `browser's site settings), then press Start camera again; ${OR_UPLOAD}`,
  absent: `No camera was found: plug one in, then press Start camera again; ${OR_UPLOAD}`,
  busy: "The camera could not be started: another program or tab may be using it. Close that one, then press " +
    `Start camera again; ${OR_UPLOAD}`,
  other: (what) => `The camera did not start (${what}): press Start camera again; ${OR_UPLOAD}`,
  ended: "The camera stopped (unplugged, or taken by another program): press Start camera again. The photos " +
    "taken so far are kept.",
  full: (n) => `${n} photos is the most one set takes (the server's limit): send these with Use these photos, ` +
    "or remove some first.",
  heavy: (mb) => `These photos are ${mb} MB, the most one upload takes (the server's limit): send them with ` +
    "Use these photos, or remove some first.",
};

/** getUserMedia's refusal ``err`` in page words. */
export function cameraProblem(err) {
  const name = (err && err.name) || "";
  if (["NotAllowedError", "SecurityError", "PermissionDeniedError"].includes(name)) return CAMERA.refused;
  if (["NotFoundError", "DevicesNotFoundError", "OverconstrainedError"].includes(name)) return CAMERA.absent;
  if (["NotReadableError", "TrackStartError", "AbortError"].includes(name)) return CAMERA.busy;
  return CAMERA.other((err && err.message) || String(err));
}
