// The board form: its spec string for the API, and a drawing of the board it describes.
const $ = (id) => document.getElementById(id);

export function boardSpec() {
  const type = $("board-type").value;
  const a = +$("board-cols").value, b = +$("board-rows").value, s = +$("board-square").value;
  if (type === "chessboard") return `chessboard:${a}x${b}:${s}mm`;
  return `charuco:${a}x${b}:${s}mm:${+$("board-marker").value}mm:${$("board-dict").value}`;
}

function draw() {
  const type = $("board-type").value;
  const charuco = type === "charuco";
  for (const n of document.querySelectorAll(".charuco-only")) n.hidden = !charuco;
  $("board-cols-label").textContent = charuco ? "Squares across" : "Inner corners across";
  $("board-rows-label").textContent = charuco ? "Squares down" : "Inner corners down";
  const a = Math.max(2, Math.min(60, +$("board-cols").value || 2));
  const b = Math.max(2, Math.min(60, +$("board-rows").value || 2));
  // a chessboard of C×R inner corners has (C+1)×(R+1) squares
  const nx = charuco ? a : a + 1, ny = charuco ? b : b + 1;
  const canvas = $("board-canvas"), ctx = canvas.getContext("2d");
  const cell = Math.min((canvas.width - 20) / nx, (canvas.height - 20) / ny);
  const x0 = (canvas.width - cell * nx) / 2, y0 = (canvas.height - cell * ny) / 2;
  ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, canvas.width, canvas.height);
  const marker = charuco ? Math.min(0.95, (+$("board-marker").value || 0) / (+$("board-square").value || 1)) : 0;
  for (let j = 0; j < ny; j++) for (let i = 0; i < nx; i++) {
    const black = (i + j) % 2 === 0;
    ctx.fillStyle = black ? "#111" : "#fff";
    ctx.fillRect(x0 + i * cell, y0 + j * cell, cell, cell);
    if (charuco && !black) { // ArUco markers sit in the white squares: a grey stand-in
      const m = cell * marker, o = (cell - m) / 2;
      ctx.fillStyle = "#777"; ctx.fillRect(x0 + i * cell + o, y0 + j * cell + o, m, m);
    }
  }
  ctx.strokeStyle = "#999"; ctx.strokeRect(x0, y0, cell * nx, cell * ny);
  // inner corners: what the detector finds
  ctx.fillStyle = "#e0561b";
  for (let j = 1; j < ny; j++) for (let i = 1; i < nx; i++) {
    ctx.beginPath(); ctx.arc(x0 + i * cell, y0 + j * cell, Math.max(1.5, cell * 0.09), 0, 2 * Math.PI); ctx.fill();
  }
  const s = +$("board-square").value;
  $("board-caption").textContent = `${nx}×${ny} squares of ${s} mm, ${(nx - 1) * (ny - 1)} inner corners (orange): ` +
    `${(nx * s).toFixed(0)}×${(ny * s).toFixed(0)} mm`;
  $("board-spec").textContent = boardSpec();
}

export function initBoard() {
  for (const id of ["board-type", "board-cols", "board-rows", "board-square", "board-marker", "board-dict"]) {
    $(id).addEventListener("input", draw);
  }
  $("board-type").addEventListener("change", () => {
    // sensible starting sizes when switching type (OpenCV's sample boards)
    const charuco = $("board-type").value === "charuco";
    $("board-cols").value = charuco ? 5 : 9; $("board-rows").value = charuco ? 7 : 6;
    draw();
  });
  draw();
}
