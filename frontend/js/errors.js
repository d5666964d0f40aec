// One banner for every failure: the API's message, in page words (words.js).
import { pageWords } from "./words.js";

const box = () => document.getElementById("error");

export function showError(err) {
  const b = box();
  b.textContent = pageWords(err && err.message ? err.message : String(err));
  b.hidden = false;
  console.error(err);
}

export function clearError() { box().hidden = true; }
