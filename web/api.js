// @ts-check
// The page's one way to the service: JSON requests under /api, the API token prompt (kept
// in a cookie EventSource sends too), and errors as values, never exceptions.

/** @typedef {{status: number, ok: boolean, data: any}} Answer  `status` 0: unreachable. */

/** One token prompt shared by concurrent requests.
 * @type {Promise<string | null> | null} */
let tokenAsked = null;

/** Send one request; JSON body in, parsed JSON (or {reason}) out.
 * @param {string} method
 * @param {string} url
 * @param {unknown} [body]
 * @returns {Promise<Answer>} */
export async function api(method, url, body) {
  /** @type {RequestInit & {headers: Record<string, string>}} */
  const init = { method, headers: {} };
  if (body !== undefined) {
    init.body = JSON.stringify(body);
    init.headers["Content-Type"] = "application/json";
  }
  let response;
  try { response = await fetch(url, init); } catch (exc) {
    const message = exc instanceof Error ? exc.message : String(exc);
    return { status: 0, ok: false, data: { reason: `service unreachable (${message})` } };
  }
  if (response.status === 401) {  // the service wants an API token: ask once and keep it in
    tokenAsked ??= Promise.resolve(window.prompt("API token (operator or read-only):"))
      .then((token) => {           // a SameSite cookie, which EventSource sends too
        if (token) document.cookie = `fleetplan_token=${encodeURIComponent(token)}; path=/; SameSite=Strict`;
        return token;
      });
    if (await tokenAsked) response = await fetch(url, init);
    if (response.status === 401) tokenAsked = null;  // wrong token: ask again next time
  }
  const text = await response.text();
  let data = null;
  try { data = text ? JSON.parse(text) : null; } catch { data = { reason: text }; }
  return { status: response.status, ok: response.ok, data: data ?? {} };
}

/** The rows of a list answer: a bare array, or a page {items|flights|missions: [...]}.
 * @param {any} data
 * @param {string} key
 * @returns {any[]} */
export function rowsOf(data, key) {
  if (Array.isArray(data)) return data;
  if (data && Array.isArray(data[key])) return data[key];
  if (data && Array.isArray(data.items)) return data.items;
  return [];
}

/** A route this service lacks (404/405 without a field): its button goes for good.
 * @param {Answer} response
 * @returns {boolean} */
export function unavailable(response) {
  return (response.status === 404 || response.status === 405) && !(response.data && response.data.field);
}

/** The field errors of a refusal: its `errors` list, or its one field and reason.
 * @param {any} data
 * @returns {{field?: string, reason: string}[]} */
export function errorsOf(data) {
  return (data && data.errors && data.errors.length) ? data.errors
    : [{ field: data && data.field, reason: (data && data.reason) || "error" }];
}
