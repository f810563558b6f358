/*
 * The explorer's JSON API from the page (no DOM: node's test runner imports it): `api` (JSON
 * in, JSON or a Blob out, a non-2xx answer thrown as an ApiError with the server's `error`,
 * `field`, `allowed` and `Retry-After`; an AbortSignal closes the connection, which cancels a
 * solve on the server), `postRetryingOnce` (one retry after a 429, the wait reported second by
 * second) and `isAbort`.
 */

/** A refused request: the server's message, the field it names and what it allows. */
export class ApiError extends Error {
  constructor(status, payload, retryAfter) {
    const msg = (payload && payload.error) || `HTTP ${status}`;
    super(msg);
    this.name = 'ApiError';
    this.status = status;
    this.field = payload && payload.field;
    this.allowed = payload && payload.allowed;
    this.retryAfterS = retryAfter;
  }
}

/** Whether `err` is a request aborted by its AbortSignal (superseded or cancelled). */
export const isAbort = (err) => !!err && err.name === 'AbortError';

export const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

/** fetch wrapper: JSON in, JSON (or a Blob) out; non-2xx answers throw ApiError. */
export async function api(method, path, body, { signal, as = 'json' } = {}) {
  const init = { method, credentials: 'same-origin', headers: {}, signal };
  if (body !== undefined) {
    init.headers['Content-Type'] = 'application/json';
    init.body = JSON.stringify(body);
  }
  const res = await fetch(path, init);
  if (!res.ok) {
    let payload = null;
    try { payload = await res.json(); } catch (_) { /* not JSON */ }
    let retry = Number(res.headers.get('Retry-After'));
    if (!Number.isFinite(retry) || res.headers.get('Retry-After') === null) {
      retry = payload && Number.isFinite(payload.retry_after_s) ? payload.retry_after_s : null;
    }
    if (!payload || !payload.error) {
      const why = {
        403: 'refused: this host or token is not allowed',
        404: 'no such endpoint',
        413: 'request too large',
        429: 'solver busy',
        500: 'server fault',
      }[res.status];
      payload = { ...(payload || {}), error: why ? `${why} (HTTP ${res.status})` : `HTTP ${res.status} ${res.statusText}` };
    }
    throw new ApiError(res.status, payload, retry);
  }
  return as === 'blob' ? res.blob() : res.json();
}

/**
 * POST with one retry after a 429 (solver busy): `onWait(secondsLeft)` each second of the wait
 * the server asked for, `onWait(0)` before the retry. `signal` aborts either request and the
 * wait.
 */
export async function postRetryingOnce(path, body, { signal, onWait = () => {} } = {}) {
  try {
    return await api('POST', path, body, { signal });
  } catch (err) {
    if (!(err instanceof ApiError) || err.status !== 429) throw err;
    const wait = err.retryAfterS != null && err.retryAfterS >= 0 ? err.retryAfterS : 1;
    const end = Date.now() + wait * 1000;
    for (;;) {
      if (signal && signal.aborted) throw new DOMException('The solve was cancelled', 'AbortError');
      const left = Math.ceil((end - Date.now()) / 1000);
      if (left <= 0) break;
      onWait(left);
      await sleep(Math.min(1000, end - Date.now()));
    }
    onWait(0);
    return api('POST', path, body, { signal });
  }
}
