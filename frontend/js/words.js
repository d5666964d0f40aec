// The API speaks to programs ("invalid request: files: Field required (see /docs for the schema)");
// the page speaks to people. Messages that name a request field are said again in page words.
export const NO_FILES = "Choose the photos first: drop images, a .zip or an observations .json on the box above " +
  "(no files chosen).";

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
