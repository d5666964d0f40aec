// The edge-width note under a thumbnail, worded by the same limits the detector judges with
// (calib_core/detection/detect_image.py): under 3 px sharp, up to 8 px accepted, past that
// rejected as too blurry. So the note never calls an image sharp that the tick rejects for blur.
import { num } from "./format.js";

export const SHARP_BELOW = 3;      // px: OpenCV's "sharp"
export const ACCEPTED_UP_TO = 8;   // px: MAX_EDGE_WIDTH, past it the image is rejected

/** {verdict: "sharp" | "soft" | "blurry", text} for an edge width in px. */
export function sharpnessNote(width) {
  const wide = `edges ${num(width, 1)} px wide`;
  if (width < SHARP_BELOW) return { verdict: "sharp", text: `sharp: ${wide}` };
  if (width <= ACCEPTED_UP_TO) return { verdict: "soft", text: `a little soft: ${wide} (sharp is under ${SHARP_BELOW} px)` };
  return { verdict: "blurry", text: `blurry: ${wide} (at most ${ACCEPTED_UP_TO} px accepted)` };
}
