// A one-line help under every setting of the upload form (the method's settings carry their own: settings.js).
// Kept here, by input id, so the form's markup stays plain.
import { el } from "./format.js";

const HELP = {
  "set-name": "A name to find this set by later; without one it is named by its number of images.",
  "board-type": "A plain chessboard, or ChArUco (a chessboard with ArUco markers: partly hidden boards still count).",
  "board-cols": "Points where four squares meet, across the board: a board of 10 squares across has 9.",
  "board-rows": "The same, down the board: a board of 7 squares down has 6.",
  "board-square": "The side of one printed square, measured: it sets the scale of the board poses, not the lens.",
  "board-marker": "The side of one printed ArUco marker.",
  "board-dict": "The ArUco dictionary the board was generated with (printed on most boards' margin).",
};

/** Add each help line once, tied to its input for screen readers. */
export function initHelp() {
  for (const [id, text] of Object.entries(HELP)) {
    const input = document.getElementById(id);
    if (!input || document.getElementById(`${id}-help`)) continue;
    input.after(el("small", { id: `${id}-help`, class: "help" }, text));
    input.setAttribute("aria-describedby", `${id}-help`);
  }
}
