// The detected corners drawn over an image of the set (a thumbnail or its enlarged view): a canvas
// laid exactly over the <img>, both in a box with the photo's own aspect ratio, so one scale maps
// photo pixels to the canvas. Drawn in the page, from the set's observations, rather than burnt into
// the thumbnail JPEG: a detection again with another board needs no new thumbnails, and the count
// drawn is the page's to show (data-corners).

/** A box holding ``img`` and an overlay canvas sized for the photo (w × h px); returns {box, canvas}. */
export function overlaidImage(img, [w, h] = [4, 3], canvasWidth = 320) {
  const canvas = document.createElement("canvas");
  canvas.className = "corner-overlay";
  canvas.width = canvasWidth; canvas.height = Math.round(canvasWidth * h / w);
  canvas.setAttribute("aria-hidden", "true");
  const box = document.createElement("span");
  box.className = "overlaid";
  box.style.aspectRatio = `${w} / ${h}`;   // CSSOM, allowed by the page's CSP (no style attribute)
  box.append(img, canvas);
  return { box, canvas };
}

/** Draw ``points`` ([[x, y], ...] photo pixels of a photo ``imageSize`` = [w, h]) on ``canvas``. */
export function drawCorners(canvas, points, imageSize) {
  const c = canvas.getContext("2d"), k = canvas.width / imageSize[0];
  const r = Math.max(1.5, canvas.width / 200);
  c.clearRect(0, 0, canvas.width, canvas.height);
  c.lineWidth = Math.max(1, r / 2);
  c.strokeStyle = "rgba(0, 0, 0, 0.75)";
  c.fillStyle = "#ffb000";   // amber on a dark rim: visible on the board's black and white squares alike
  for (const [x, y] of points) {
    // pixel centres: a photo pixel x spans [x - 0.5, x + 0.5], the canvas starts at its left edge
    c.beginPath(); c.arc((x + 0.5) * k, (y + 0.5) * k, r, 0, 2 * Math.PI); c.fill(); c.stroke();
  }
}
