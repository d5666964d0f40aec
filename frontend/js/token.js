// The access token of a server started with FREECAL_TOKEN: kept for this tab only
// (sessionStorage: gone when the tab closes), asked for once when the API answers 401.
import { el } from "./format.js";

const KEY = "freecal.token";
let asking = null;   // one form for every request that meets a 401 at the same time

export function currentToken() { return sessionStorage.getItem(KEY) || ""; }

export function storeToken(token) {
  if (token) sessionStorage.setItem(KEY, token);
  else sessionStorage.removeItem(KEY);
}

/** `/?token=XYZ` opens the page with a token: keep it, and take it out of the address bar (and history). */
export function adoptTokenFromAddress() {
  const url = new URL(window.location.href);
  if (!url.searchParams.has("token")) return;
  storeToken(url.searchParams.get("token"));
  url.searchParams.delete("token");
  window.history.replaceState(window.history.state, "", url.pathname + url.search + url.hash);
}

/** Show the token form (once, however many requests wait on it); resolves when a token was entered. */
export function askForToken(message) {
  if (!asking) asking = showForm(message).finally(() => { asking = null; });
  return asking;
}

function showForm(message) {
  return new Promise((resolve) => {
    const input = el("input", { id: "token-input", type: "password", autocomplete: "current-password", required: true });
    const form = el("form", { id: "token-form", class: "card", style: "margin: 1rem auto; max-width: 40rem" },
      el("h2", {}, "Access token"),
      el("p", { class: "muted" }, currentToken() ? "That token was refused: check it and try again." : message),
      el("label", { for: "token-input" }, "Token (kept for this tab only)"), " ", input, " ",
      el("button", { type: "submit", class: "primary", style: "width: auto" }, "Use token"));
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      storeToken(input.value.trim());
      form.remove();
      resolve(currentToken());
    });
    document.querySelector("main").before(form);
    input.focus();
  });
}
