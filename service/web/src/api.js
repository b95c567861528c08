// The service's REST routes and event stream, as the view uses them (same origin: no token, no CDN).

/** GET a JSON route; throws with the problem's detail on an error status. */
export async function getJSON(url) {
  return answer(await fetch(url, { headers: { Accept: "application/json" } }));
}

/** POST a JSON body; throws with the problem's detail on an error status. */
export async function postJSON(url, body) {
  return answer(await fetch(url, {
    method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body),
  }));
}

/** PUT a JSON body; throws with the problem's detail on an error status. */
export async function putJSON(url, body) {
  return answer(await fetch(url, {
    method: "PUT", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body),
  }));
}

async function answer(response) {
  const body = response.headers.get("content-type")?.includes("json") ? await response.json() : null;
  if (!response.ok) throw new Error(body?.detail ?? `HTTP ${response.status} from ${response.url}`);
  return body;
}

/** The GLB bytes of a geometry (GET /geometries/{gid}): immutable, so fetched once per page. */
const glbCache = new Map();
export function geometryBytes(gid) {
  if (!glbCache.has(gid)) {
    glbCache.set(gid, fetch(`/geometries/${gid}`).then((r) => {
      if (!r.ok) throw new Error(`geometry ${gid}: HTTP ${r.status}`);
      return r.arrayBuffer();
    }));
  }
  return glbCache.get(gid);
}

/**
 * Follow the scene's server-sent events (GET /scenes/{id}/events): `handlers[name](data)` per event.
 * EventSource reconnects by itself after the stream ends (the service closes each after a few minutes);
 * `onState(text)` hears whether we are connected.
 */
export function followEvents(sceneId, handlers, onState) {
  const source = new EventSource(`/scenes/${sceneId}/events`);
  for (const name of ["hello", "scene", "push", "job", "result", "resync", "deleted"]) {
    source.addEventListener(name, (e) => handlers[name]?.(JSON.parse(e.data)));
  }
  source.onopen = () => onState("live");
  source.onerror = () => onState(source.readyState === EventSource.CLOSED ? "closed" : "reconnecting");
  return source;
}
