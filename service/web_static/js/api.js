// Talking to the illumix service: JSON with its one error shape, and the `arrays` container
// (README "Transfer less"; encoder service/arrays_format.py).

/** An error answer's one line ({detail, status, code, loc}), or the HTTP status when there is none. */
async function failure(response) {
  try {
    const body = await response.json();
    if (body && typeof body.detail === "string") return new Error(body.detail);
  } catch { /* not JSON */ }
  return new Error(`${response.status} ${response.statusText}`);
}

export async function getJSON(url, options = {}) {
  const r = await fetch(url, options);
  if (!r.ok) throw await failure(r);
  return r.json();
}

/** POST a multipart form (uploads); `token` becomes `Authorization: Bearer <token>` when given. */
export async function postForm(url, form, token) {
  const headers = token ? { Authorization: `Bearer ${token}` } : {};
  const r = await fetch(url, { method: "POST", body: form, headers });
  if (!r.ok) throw await failure(r);
  return r.json();
}

const TYPES = { "<f4": Float32Array, "|u1": Uint8Array, "|b1": Uint8Array, "<u2": Uint16Array, "<i4": Int32Array };

/**
 * Decode an arrays container: b"ILLUMIXA", version 1, 3 reserved bytes, uint32 LE header length,
 * the JSON header, then each array's C-order bytes at its 64-byte aligned offset.
 * Returns {arrays: {name: {data: TypedArray (a view, no copy), shape}}, meta}.
 */
export function decodeArrays(buffer) {
  const magic = new TextDecoder().decode(new Uint8Array(buffer, 0, 8));
  const view = new DataView(buffer);
  if (magic !== "ILLUMIXA" || view.getUint8(8) !== 1) throw new Error("not an illumix arrays container (version 1)");
  const n = view.getUint32(12, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 16, n)));
  const arrays = {};
  for (const [name, e] of Object.entries(header.arrays)) {
    const T = TYPES[e.dtype];
    if (!T) throw new Error(`arrays container: ${name} has dtype ${e.dtype}, which the page does not read`);
    arrays[name] = { data: new T(buffer, e.offset, e.nbytes / T.BYTES_PER_ELEMENT), shape: e.shape };
  }
  return { arrays, meta: header.meta };
}

/** The `Server-Timing` header as {name: ms}. */
function serverTiming(header) {
  const out = {};
  for (const part of (header || "").split(",")) {
    const m = part.trim().match(/^([\w-]+);dur=([\d.]+)/);
    if (m) out[m[1]] = Number(m[2]);
  }
  return out;
}

/** GET an arrays container (+ `timing`, the server's ms); `signal` aborts it (a newer update supersedes it). */
export async function getArrays(url, signal) {
  const r = await fetch(url, { signal });
  if (!r.ok) throw await failure(r);
  return { ...decodeArrays(await r.arrayBuffer()), timing: serverTiming(r.headers.get("Server-Timing")) };
}
