// One banner for every failure: the API's message as it gave it.
const box = () => document.getElementById("error");

export function showError(err) {
  const b = box();
  b.textContent = err && err.message ? err.message : String(err);
  b.hidden = false;
  console.error(err);
}

export function clearError() { box().hidden = true; }
